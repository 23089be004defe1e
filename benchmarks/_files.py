"""Atomic JSON writes for the benchmarks' per-run result files: a kill mid-write leaves the old file (or none)."""

from __future__ import annotations

import json
import os


def write_json(path, obj, *, indent: int = 1) -> None:
    """Write ``obj`` as JSON to ``path`` through ``path.tmp`` and ``os.replace``, so readers never see half a file."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=indent)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
