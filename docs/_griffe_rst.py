"""A griffe extension for the API reference: the docstrings' reStructuredText habits, rendered as Markdown.

The docstrings write Sphinx roles (``:class:`Link```, ``:func:`~lagrange.tasks.balanced```), simple tables bordered
by ``====`` and ``::`` before a literal block. mkdocstrings renders Markdown, so here, before rendering,

- a role becomes an optional cross-reference (a link where the target is in the reference, plain code where not),
- a simple table becomes a Markdown table (a row whose first cell is blank continues the row above),
- a trailing ``::`` becomes ``:`` (the indented block after it is already a Markdown code block),
- a field list (three or more lines ``name: text`` or ``a, b: text`` at one indent, continued by deeper lines;
  not a Google section such as ``Args:``, which mkdocstrings parses itself) becomes a bullet list,
- ``] [`` outside code spans no longer reads as a Markdown reference link (``[1e-5] [lr_schedule = linear]``),
- the first paragraph is reflowed so that its first line is its first sentence: the API reference's summary tables
  show a docstring's first line, and a sentence wrapped over two lines would be cut (the rendered paragraph is the
  same, its lines being joined by Markdown).

Loaded by ``mkdocs.yml`` (``extensions: [docs/_griffe_rst.py]``); the library's docstrings are not changed.
"""

from __future__ import annotations

import html
import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|mod|data|meth|attr|obj|exc):`(~?)([^`<>]+)`")
BORDER = re.compile(r"^(\s*)=+(?:\s+=+)+\s*$")


def _resolve(obj: griffe.Object, name: str) -> str:
    """The full path of ``name`` as seen from ``obj``'s scope, or ``name`` itself if griffe cannot tell."""
    head, _, rest = name.partition(".")
    scope = obj
    while scope is not None:
        try:
            full = scope.resolve(head)
        except Exception:  # noqa: BLE001 - griffe raises NameResolutionError or a lookup error
            scope = scope.parent
            continue
        return f"{full}.{rest}" if rest else full
    return name


def _roles(obj: griffe.Object, text: str) -> str:
    def repl(m: re.Match) -> str:
        tilde, name = m.groups()
        shown = name.rsplit(".", 1)[-1] if tilde else name
        target = _resolve(obj, name)
        return f'<autoref identifier="{html.escape(target)}" optional><code>{html.escape(shown)}</code></autoref>'

    return ROLE.sub(repl, text)


def _cells(line: str, spans: list[tuple[int, int]]) -> list[str]:
    cells = []
    for k, (start, _end) in enumerate(spans):
        stop = None if k == len(spans) - 1 else spans[k + 1][0]
        cells.append(line[start:stop].strip())
    return cells


def _table(lines: list[str], spans: list[tuple[int, int]], header: list[str] | None) -> list[str]:
    rows: list[list[str]] = []
    for line in lines:
        if not line.strip():
            continue
        cells = _cells(line, spans)
        if rows and not cells[0]:  # a continuation line
            rows[-1] = [f"{a} {b}".strip() for a, b in zip(rows[-1], cells)]
        else:
            rows.append(cells)
    head = header if header is not None else [""] * len(spans)

    def fmt(cells):
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return ["", fmt(head), "|" + "---|" * len(spans), *(fmt(r) for r in rows), ""]


def _tables(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        if not BORDER.match(lines[i]):
            out.append(lines[i])
            i += 1
            continue
        spans = [(m.start(), m.end()) for m in re.finditer(r"=+", lines[i])]
        borders, j = [i], i + 1
        while j < len(lines):
            if BORDER.match(lines[j]):
                borders.append(j)
                if j + 1 >= len(lines) or not lines[j + 1].strip():
                    break
            j += 1
        if len(borders) < 2:  # not a table after all
            out.append(lines[i])
            i += 1
            continue
        if len(borders) >= 3:
            header = (_cells(" ".join(lines[borders[0] + 1: borders[1]]), spans) if borders[1] == borders[0] + 2
                      else None)
            body = lines[borders[1] + 1: borders[-1]]
        else:
            header, body = None, lines[borders[0] + 1: borders[-1]]
        out.extend(_table([ln for ln in body if not BORDER.match(ln)], spans, header))
        i = borders[-1] + 1
    return "\n".join(out)


def _literal_blocks(text: str) -> str:
    return re.sub(r"::\n", ":\n", text)


FIELD = re.compile(r"^(\s*)([A-Za-z_]\w*(?:, [A-Za-z_]\w*)*): (\S.*)$")
SECTION = re.compile(r"^\s*(Args|Arguments|Parameters|Params|Keyword Args|Keyword Arguments|Other Parameters|Returns|"
                     r"Return|Yields|Raises|Exceptions|Warns|Attributes|Examples?|Notes?|Methods|Functions|Classes|"
                     r"Modules|Receives|Warnings?|See Also|References):\s*$")


def _field_lists(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    i, in_section, fence = 0, False, False
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            fence = not fence
        if SECTION.match(line):
            in_section = True
        elif not line.strip():
            in_section = False
        m = None if (fence or in_section) else FIELD.match(line)
        if m is None:
            out.append(line)
            i += 1
            continue
        indent, items, j = len(m.group(1)), [], i
        while j < len(lines):
            f = FIELD.match(lines[j])
            if f and len(f.group(1)) == indent:
                items.append([f.group(2), f.group(3)])
            elif items and lines[j].strip() and len(lines[j]) - len(lines[j].lstrip()) > indent:
                items[-1][1] += " " + lines[j].strip()
            else:
                break
            j += 1
        if len(items) < 3:
            out.append(line)
            i += 1
            continue
        if out and out[-1].strip():
            out.append("")
        out.extend(f"- {', '.join(f'`{n}`' for n in names.split(', '))}: {desc}" for names, desc in items)
        out.append("")
        i = j
    return "\n".join(out)


CODE = re.compile(r"(``.+?``|`[^`]+`)")
SENTENCE_END = re.compile(r"[.!?] +(?=[A-Z`(:\\])")
ABBREVIATIONS = ("e.g.", "i.e.", "etc.", "vs.", "cf.")


def _first_sentence_first(text: str) -> str:
    """``text`` with its first paragraph's lines joined and broken once, after its first sentence."""
    lines = text.split("\n")
    k = 0
    while k < len(lines) and lines[k].strip():
        k += 1
    if k < 2 or lines[0].lstrip().startswith(("```", "-", "*", "|", "=", ">", "..")) or lines[0].startswith(" "):
        return text
    joined = " ".join(line.strip() for line in lines[:k])
    masked = CODE.sub(lambda m: "x" * len(m.group()), joined)
    for m in SENTENCE_END.finditer(masked):
        head = joined[: m.start() + 1]
        if head.endswith(ABBREVIATIONS):
            continue
        rest = joined[m.end():]
        return "\n".join([head, rest, *lines[k:]])
    return "\n".join([joined, *lines[k:]])


def _no_reference_links(text: str) -> str:
    parts = CODE.split(text)
    return "".join(p if k % 2 else p.replace("] [", "]&#32;[") for k, p in enumerate(parts))


class RstDocstrings(griffe.Extension):
    """Rewrite every docstring of a loaded package (see the module docstring)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        self._visit(pkg, set())

    def _visit(self, obj: griffe.Object, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        if obj.docstring is not None:
            text = obj.docstring.value
            text = _field_lists(_literal_blocks(_tables(_first_sentence_first(text))))
            obj.docstring.value = _roles(obj, _no_reference_links(text))
        for member in obj.members.values():
            if not member.is_alias:
                self._visit(member, seen)
