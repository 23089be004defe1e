"""The house rules of issue 40 over the library (lagrange, policies, optim): no module imports a private
(leading-underscore) name from another module (a private module, ``lagrange.math.scalar``, is fine), and no module is
longer than 450 lines; no module both reads and writes MJCF. The check itself is checked on a snippet that breaks each
rule."""

import ast
import importlib.util
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
AREA = [*sorted((ROOT / "optim").rglob("*.py")), *sorted((ROOT / "policies").rglob("*.py")),
        *sorted((ROOT / "lagrange").rglob("*.py"))]
MAX_LINES = 450


def private_imports(source: str) -> list[str]:
    """``module.name`` of every ``from module import _name`` in ``source`` where ``_name`` is not itself a module
    (dunder names aside)."""
    return [f"{node.module}.{alias.name}" for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.ImportFrom) for alias in node.names
            if alias.name.startswith("_") and not alias.name.startswith("__")
            and not _is_module(f"{node.module}.{alias.name}")]


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # its parent is a module, not a package
        return False


def test_no_private_name_crosses_a_module_and_no_module_is_long():
    assert len(AREA) > 60
    for path in AREA:
        source = path.read_text()
        assert private_imports(source) == [], path
        assert len(source.splitlines()) <= MAX_LINES, (path, len(source.splitlines()))
    found = private_imports("from lagrange.tasks.base import _check, wrap\nfrom concurrent.futures import _base\n"
                            "from lagrange.integrate import _forward\nfrom json import __version__\n")
    assert found == ["lagrange.tasks.base._check", "lagrange.integrate._forward"]  # a private module is fine


def test_no_module_both_reads_and_writes_mjcf():
    """Reading (``from_mjcf``), writing (``to_mjcf``) and running MuJoCo live in modules of their own."""
    for path in sorted((ROOT / "lagrange").rglob("*.py")):
        source = path.read_text()
        defines = {node.name for node in ast.walk(ast.parse(source)) if isinstance(node, ast.FunctionDef)}
        assert not {"from_mjcf", "to_mjcf"} <= defines, path
