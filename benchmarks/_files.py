"""Atomic writes for the benchmarks' result files: a kill mid-write leaves the old file (or none)."""

from __future__ import annotations

import json
import os


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` through ``path.tmp`` and ``os.replace``, so readers never see half a file;
    the folder is created if missing."""
    path = os.fspath(path)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def repo_relative(path) -> str:
    """``path`` relative to the repository root when it lies inside it (so result files do not record this
    machine's folders), else as given."""
    path = os.fspath(path)
    full = os.path.abspath(path)
    return os.path.relpath(full, REPO) if os.path.commonpath([full, REPO]) == REPO else path


def write_json(path, obj, *, indent: int = 1) -> None:
    """:func:`write_text` of ``obj`` as JSON."""
    write_text(path, json.dumps(obj, indent=indent))
