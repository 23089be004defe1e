"""Atomic, versioned checkpoints of a training state: a JSON header line + equinox leaf serialisation.

File layout: one line of UTF-8 JSON (``{"format": "lagrange-checkpoint", "version": 1, "config":
..., "iteration": ..., "history": [...], ...}``) followed by ``eqx.tree_serialise_leaves`` bytes of
the state. No pickle. Writes go to a temporary file in the same folder, are flushed and fsynced,
and then ``os.replace``-d over the target, so a kill mid-write leaves the previous checkpoint intact.
"""

from __future__ import annotations

import io
import json
import os
import tempfile

import equinox as eqx

FORMAT = "lagrange-checkpoint"
VERSION = 2
"""Version 2: one format for every algorithm (header with ``config``, ``identity`` of the task and policy, ``seed``,
``history``, ``curve``). Version 1 (CE-APG/PAPG/APG before the unified trainer) is refused."""


class CheckpointError(ValueError):
    """A checkpoint that is corrupt, of another format version, or from a different config."""


def save(path, state, *, config: dict, **header) -> None:
    """Atomically write ``state`` (a pytree of arrays) with ``config`` and any JSON-able ``header`` fields."""
    head = {"format": FORMAT, "version": VERSION, "config": config, **header}
    buf = io.BytesIO()
    eqx.tree_serialise_leaves(buf, state)
    _write_atomically(path, json.dumps(head).encode() + b"\n" + buf.getvalue(), prefix=".ckpt-")


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a kill mid-write leaves the old file, or none); the folder is created
    if missing."""
    _write_atomically(path, text.encode(), prefix=".write-")


def write_json(path, obj, *, indent: int = 1) -> None:
    """:func:`write_text` of ``obj`` as JSON: result files that a killed run never leaves half-written."""
    write_text(path, json.dumps(obj, indent=indent))


def _write_atomically(path, data: bytes, *, prefix: str) -> None:
    """Write ``data`` to a temporary file beside ``path``, flush and fsync it, then ``os.replace`` it over ``path``."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=prefix, dir=folder)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file an ordinary file's mode
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def read_header(path) -> dict:
    """The JSON header of a checkpoint; raises :class:`CheckpointError` if it is not one."""
    path = os.fspath(path)
    with open(path, "rb") as f:
        line = f.readline()
    try:
        head = json.loads(line)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise CheckpointError(f"{path} is not a lagrange checkpoint (unreadable header): {err}") from None
    if not isinstance(head, dict) or head.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a lagrange checkpoint (header format is {head!r:.80})")
    if head.get("version") != VERSION:
        raise CheckpointError(f"{path} has checkpoint format version {head.get('version')!r}; this code reads version "
                              f"{VERSION} (one format for every algorithm, written by optim.train). Start the run "
                              f"afresh, or read it with the code that wrote it")
    return head


def config_difference(saved: dict, config: dict, *, saved_as: str, now_as: str) -> str:
    """Every field whose value differs between two config dicts, as ``field: <saved_as> old, <now_as> new``
    joined by ``; `` (empty when they agree)."""
    diff = sorted(k for k in set(saved) | set(config) if saved.get(k) != config.get(k))
    return "; ".join(f"{k}: {saved_as} {saved.get(k)!r}, {now_as} {config.get(k)!r}" for k in diff)


def load(path, like, *, config: dict | None = None):
    """``(state, header)`` from ``path``; ``like`` is a state of the same structure (e.g. ``trainer.init(key)``).

    If ``config`` is given it must equal the checkpoint's config; otherwise the differing fields are named.
    """
    path = os.fspath(path)
    head = read_header(path)
    if config is not None and head["config"] != config:
        detail = config_difference(head["config"], config, saved_as="checkpoint", now_as="requested")
        raise CheckpointError(f"{path} was written with a different config ({detail})")
    with open(path, "rb") as f:
        f.readline()
        payload = f.read()
    try:
        buf = io.BytesIO(payload)
        state = eqx.tree_deserialise_leaves(buf, like)
        if buf.read(1):
            raise ValueError("trailing bytes after the last leaf")
    except Exception as err:  # numpy / equinox raise several types on truncated or garbled data
        raise CheckpointError(f"{path} is corrupt (its state does not deserialise: {err})") from None
    return state, head
