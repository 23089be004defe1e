"""Atomic, versioned checkpoints of a training state: a JSON header line + equinox leaf serialisation, with a digest.

File layout: one line of UTF-8 JSON (``{"format": "lagrange-checkpoint", "version": 2, "config": ..., "iteration":
..., "history": [...], ..., "digest": "<sha256>"}``) followed by ``eqx.tree_serialise_leaves`` bytes of the state.
No pickle. The digest is the SHA-256 of the header line without it and the state's bytes, so a changed byte anywhere
in the file is refused on reading (files written before the digest existed have none and are read unchecked). Writes
go to a temporary file in the same folder, are flushed and fsynced, and then ``os.replace``-d over the target, so a
kill mid-write leaves the previous checkpoint intact.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import tempfile

import equinox as eqx
import jax
import numpy as np

from optim.base import config_difference

__all__ = ["FORMAT", "VERSION", "CheckpointError", "save", "load", "read_header", "config_difference", "nan_leaves",
           "check_writable", "write_text", "write_json", "strict_json"]

FORMAT = "lagrange-checkpoint"
VERSION = 2
"""Version 2: one format for every algorithm (header with ``config``, ``identity`` of the task and policy, ``seed``,
``history``, ``curve``; since the digest was added, ``digest``). Version 1 (CE-APG/PAPG/APG before the unified
trainer) is refused."""


class CheckpointError(ValueError):
    """A checkpoint that is corrupt, of another format version, or from a different config, task or policy."""


def save(path: str | os.PathLike, state, *, config: dict, **header) -> None:
    """Atomically write a checkpoint.

    Args:
        path: the file.
        state: a pytree of arrays (a trainer's state).
        config: the config's JSON dict (:func:`optim.base.config_to_dict`).
        **header: any JSON-able header fields (``identity``, ``seed``, ``iteration``, ``history``, ...); a
            ``digest`` given here is replaced by the file's own.
    """
    header.pop("digest", None)
    head = {"format": FORMAT, "version": VERSION, "config": config, **header}
    buf = io.BytesIO()
    eqx.tree_serialise_leaves(buf, state)
    line = json.dumps(head).encode()
    digest = _digest(line, buf.getvalue())
    _write_atomically(path, json.dumps({**head, "digest": digest}).encode() + b"\n" + buf.getvalue(), prefix=".ckpt-")


def _digest(header_line: bytes, payload: bytes) -> str:
    return hashlib.sha256(header_line + b"\n" + payload).hexdigest()


def check_writable(path: str | os.PathLike, *, what: str = "checkpoint") -> None:
    """Check, before any work, that a file can be written at ``path`` (its folder is created if missing).

    Args:
        path: the file to be written later.
        what: what to call it in the error (``"checkpoint"``, ``"--out"``).

    Raises:
        ValueError: naming ``what`` and the path, when ``path`` is a folder, or its folder is a file or cannot be
            created or written to.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise ValueError(f"{what} {path!r} is a folder; give a file path (e.g. {os.path.join(path, 'run.eqx')!r})")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        why = "is not a folder" if os.path.exists(folder) and not os.path.isdir(folder) else "is not writable"
        raise ValueError(f"{what} {path!r} cannot be written: its folder {folder!r} {why} ({err.strerror or err})") \
            from None


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write text atomically: a kill mid-write leaves the old file, or none.

    Args:
        path: the file; its folder is created if missing.
        text: what to write (UTF-8).
    """
    _write_atomically(path, text.encode(), prefix=".write-")


def write_json(path: str | os.PathLike, obj, *, indent: int = 1, strict: bool = False) -> None:
    """:func:`write_text` of ``obj`` as JSON: result files that a killed run never leaves half-written.

    Args:
        path: the file.
        obj: a JSON-able object.
        indent: JSON indentation.
        strict: write NaN and infinities as ``null`` (strict JSON, :func:`strict_json`); otherwise Python's
            ``NaN``/``Infinity`` extension.
    """
    write_text(path, json.dumps(strict_json(obj) if strict else obj, indent=indent, allow_nan=not strict))


def strict_json(obj):
    """What strict JSON can hold: every non-finite float (NaN, +-inf) replaced by None.

    Args:
        obj: a JSON-able object (dicts, lists and tuples are gone through recursively; tuples become lists).
    """
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    return obj


def _write_atomically(path, data: bytes, *, prefix: str) -> None:
    """Write ``data`` to a temporary file beside ``path``, flush and fsync it, then ``os.replace`` it over ``path``."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path!r} is a folder; give a file path to write")
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


def read_header(path: str | os.PathLike) -> dict:
    """The JSON header of a checkpoint (its ``digest`` unchecked: :func:`load` checks it).

    Args:
        path: the file.

    Raises:
        CheckpointError: if ``path`` is not a checkpoint of this format version.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        line = f.readline()
    return _parse_header(path, line)


def _parse_header(path: str, line: bytes) -> dict:
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


def nan_leaves(tree) -> list[str]:
    """Where a pytree holds a NaN.

    Args:
        tree: a pytree of arrays.

    Returns:
        The paths (``jax.tree_util.keystr``) of the floating leaves that hold a NaN.
    """
    out = []
    for path, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]:
        if not jax.dtypes.issubdtype(getattr(leaf, "dtype", np.float64), np.inexact):  # integers, PRNG keys
            continue
        a = np.asarray(leaf)
        if np.isnan(a).any():
            out.append(jax.tree_util.keystr(path))
    return out


def load(path: str | os.PathLike, like, *, config: dict | None = None):
    """Read a checkpoint.

    Args:
        path: the file.
        like: a state of the same structure (e.g. ``trainer.init(key)``).
        config: if given, the checkpoint's config must equal it.

    Returns:
        ``(state, header)``.

    Raises:
        CheckpointError: naming the differing config fields; when the file's content does not match its digest
            (a changed byte), its state does not deserialise into ``like``, or the state holds a NaN.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        line = f.readline()
        payload = f.read()
    head = _parse_header(path, line)
    if "digest" in head:
        recorded = head.pop("digest")
        if _digest(json.dumps(head).encode(), payload) != recorded:
            raise CheckpointError(f"{path} is corrupt: its content does not match the digest its header records (a "
                                  f"byte changed since it was written). Start the run afresh without resume")
    if config is not None and head["config"] != config:
        detail = config_difference(head["config"], config, saved_as="checkpoint", now_as="requested")
        raise CheckpointError(f"{path} was written with a different config ({detail})")
    try:
        buf = io.BytesIO(payload)
        state = eqx.tree_deserialise_leaves(buf, like)
        if buf.read(1):
            raise ValueError("trailing bytes after the last leaf")
    except Exception as err:  # numpy / equinox raise several types on truncated or garbled data
        raise CheckpointError(f"{path} is corrupt (its state does not deserialise: {err})") from None
    bad = nan_leaves(state)
    if bad:
        raise CheckpointError(f"{path} holds a NaN in its state ({', '.join(bad)}); a run never saves one, so the "
                              f"file is damaged. Start the run afresh without resume")
    return state, head
