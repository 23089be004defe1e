"""Muscles on a spatial tree (:class:`lagrange.model.muscles.Muscle`): their paths' lengths and their forces as
spatial forces on the links.

Every waypoint is carried into the frame of the link that moves it (a body welded below a link's body placed through
the welded bodies, :func:`~lagrange.rbda.kinematics.body_frames_in_links`); a waypoint on a body welded to the world
stays where it is written. At ``q`` its position is ``o + p + R x`` (the link's tree's reference point, the link's
origin from it and its rotation, :class:`~lagrange.rbda.kinematics.Kinematics`). A muscle's length is the sum of its
segments' ``|x_end - x_start|``. Its generalized force ``tau = -F dL/dq`` is computed as ``-F sum_i J_i^T dL/dx_i``:
``dL/dx_i`` by differentiating the segments' lengths with respect to their ends (``jax.vjp``, the tensions as the
cotangent), each end's ``-F dL/dx_i`` a force on its link, entering the recursive Newton-Euler algorithm as the
spatial force ``(s x f, f)`` at the reference point, as contact forces do (:mod:`lagrange.rbda.contact`); by the chain
rule this is ``-F dL/dq``. Waypoints on the world and segments within one link add no force.

Layout, for speed: every segment's two ends are computed from their links' frames picked by products with static 0/1
matrices (segment x link), with the batch as the last axis, ``(segments, 3, B)``. No gather runs, so no scatter-add
runs in the gradient: on a CPU (DFlex's SNU humanoid, 636 waypoints, B = 64) batch-first gathers of the waypoints took
ten times the kinematics' time, and the scatters of their gradient twice that again.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.math import spatial as al
from lagrange.model.tree import WORLD, Tree
from lagrange.rbda.kinematics import Kinematics, body_frames_in_links
from lagrange.rbda.structure import Structure

__all__ = ["Paths", "muscle_forces", "muscle_lengths", "muscle_torques", "muscle_wrenches"]


class Paths:
    """The static layout of a tree's muscles: every segment's two ends, each in the frame of its link, the segments
    grouped by their two links.

    Attributes:
        start_link, end_link: each segment's ends' links (``n``, one past the last link: the world), ``(S,)``.
        start, end: the ends in their links' frames (in the world's for the world), ``(S, 3)``; NumPy where the
            muscles' points and the bodies' placements are concrete.
        muscle: each segment's muscle, ``(S,)``.
        moving: the segments whose ends lie on two different links (those that transmit force), ``(S,)`` bool.
        pairs: ``{(start link, end link): segments}``, in the order the segments come.
        n: the number of muscles; links: of links.
    """

    def __init__(self, tree: Tree, structure: Structure):
        frames = body_frames_in_links(structure)
        world = _world_frames(tree, structure)
        links, points, muscle, first = [], [], [], []
        for m, mu in enumerate(tree.muscles):
            first.append(len(points))
            for k, b in enumerate(mu.bodies):
                R, p = frames[b] if b in frames else world[b]
                links.append(structure.body_link[b] if b in frames else structure.n)
                points.append(_apply(R, p, mu.points[k]))
            muscle += [m] * (len(mu.bodies) - 1)
        starts = np.concatenate([np.arange(f, f + len(mu.bodies) - 1) for f, mu in zip(first, tree.muscles)]) \
            if tree.muscles else np.zeros(0, int)
        links = np.array(links, int)
        xp = jnp if any(isinstance(x, jax.core.Tracer) for x in points) else np
        points = xp.stack(points) if points else np.zeros((0, 3))
        self.start_link, self.end_link = links[starts], links[starts + 1]
        self.start, self.end = points[starts], points[starts + 1]
        self.muscle = np.array(muscle, int)
        self.moving = self.start_link != self.end_link
        self.pairs = {}
        for i, key in enumerate(zip(self.start_link.tolist(), self.end_link.tolist())):
            self.pairs.setdefault(key, []).append(i)
        self.pairs = {key: np.array(rows) for key, rows in self.pairs.items()}
        self.n, self.links = len(tree.muscles), structure.n


def _apply(R, p, x):
    if any(isinstance(v, jax.core.Tracer) for v in (R, p, x)):
        return jnp.asarray(p) + jnp.asarray(R) @ x
    return np.asarray(p, float) + np.asarray(R, float) @ np.asarray(x, float)


def _world_frames(tree: Tree, structure: Structure) -> dict:
    """``{body: (R, p)}`` in the world for the bodies welded to it (no joint between them and the world)."""
    out = {}
    for b, body in enumerate(tree.bodies):
        if structure.body_link[b] != WORLD:
            continue
        Rb = al.quat_to_matrix(np.asarray(body.quat, float), np)
        pb = np.asarray(body.pos) if not isinstance(body.pos, jax.core.Tracer) else body.pos
        if tree.parents[b] == WORLD:
            out[b] = (Rb, pb)
        else:
            Rp, pp = out[tree.parents[b]]
            out[b] = (Rp @ Rb, _apply(Rp, pp, pb))
    return out


def _batch_last(x, tail: int):
    """``x (*batch, *tail)`` as ``(*tail, B)`` (the batch flattened into the last axis)."""
    batch = x.shape[:x.ndim - tail]
    x = x.reshape((int(np.prod(batch, dtype=int)),) + x.shape[x.ndim - tail:])
    return jnp.moveaxis(x, 0, -1)


def _batch_first(x, batch):
    """The inverse of :func:`_batch_last`: ``(*tail, B)`` as ``(*batch, *tail)``."""
    x = jnp.moveaxis(x, -1, 0)
    return x.reshape(tuple(batch) + x.shape[1:])


class _Frames:
    """The links' frames with the batch last, the world appended as a last link: rotations ``(n + 1, 3, 3, B)`` and
    origins in the world ``(n + 1, 3, B)``, and with ``velocity`` the spatial velocities ``(n + 1, 6, B)`` and the
    reference points ``(n + 1, 3, B)``."""

    def __init__(self, k: Kinematics, velocity: bool = False):
        R, x0, o = _batch_last(k.R, 3), _batch_last(k.o + k.p, 2), _batch_last(k.o, 2)
        B, dtype = R.shape[-1], R.dtype
        eye = jnp.broadcast_to(jnp.eye(3, dtype=dtype)[None, :, :, None], (1, 3, 3, B))
        zero = jnp.zeros((1, 3, B), dtype)
        self.R, self.x0, self.o = (jnp.concatenate([R, eye]), jnp.concatenate([x0, zero]),
                                   jnp.concatenate([o, zero]))
        self.v = jnp.concatenate([_batch_last(k.v, 2), jnp.zeros((1, 6, B), dtype)]) if velocity else None

    def place(self, link: int, local):
        """Points fixed on ``link`` (``(k, 3)`` in its frame) in the world, ``(k, 3, B)``: one product."""
        return self.x0[link][None] + jnp.einsum("kj,ijb->kib", jnp.asarray(local, self.R.dtype), self.R[link])

    def velocity(self, link: int, x):
        """The velocities ``(k, 3, B)`` of points of ``link`` at ``x (k, 3, B)`` (zero on the world)."""
        v = self.v[link][None]
        return v[:, 3:] + _cross(v[:, :3], x - self.o[link][None])


def _pairs(frames: _Frames, paths: Paths, moving_only: bool):
    """Per pair of links ``(a, b)``: ``(a, b, segments, xs, xe)``, the segments' ends in the world ``(k, 3, B)``: no
    gather, each link's points one product with its rotation."""
    for (a, b), rows in paths.pairs.items():
        if moving_only and a == b:
            continue
        yield a, b, rows, frames.place(a, paths.start[rows]), frames.place(b, paths.end[rows])


def _segment_lengths(xs, xe):
    """``|xe - xs|`` per segment ``(S, B)`` from its ends ``(S, 3, B)``; a zero-length segment has length 0 and a
    finite gradient, 0."""
    d = xe - xs
    dd = jnp.sum(d * d, axis=1)
    safe = jnp.where(dd > 0, dd, 1.0)
    return jnp.where(dd > 0, jnp.sqrt(safe), 0.0)


def _per_muscle(paths: Paths, segments):
    """The static 0/1 matrix ``(muscles, S)`` summing the ``segments``' values into their muscles."""
    return (np.arange(paths.n)[:, None] == paths.muscle[segments][None, :]).astype(float)


def _lengths(frames: _Frames, paths: Paths, velocity: bool = False):
    """Each muscle's path length ``(n, B)``, and with ``velocity`` its rate (else ``None``)."""
    L = Ld = 0.0
    for a, b, rows, xs, xe in _pairs(frames, paths, moving_only=False):
        E = jnp.asarray(_per_muscle(paths, rows), xs.dtype)
        if velocity:
            seg, rate = jax.jvp(_segment_lengths, (xs, xe), (frames.velocity(a, xs), frames.velocity(b, xe)))
            Ld = Ld + E @ rate
        else:
            seg = _segment_lengths(xs, xe)
        L = L + E @ seg
    return L, (Ld if velocity else None)


def muscle_lengths(tree: Tree, q):
    """The muscles' path lengths ``L(q)`` [m], ``(..., muscles)`` (the public face: :func:`lagrange.muscle_lengths`)."""
    k = Kinematics(tree, q)
    return _batch_first(_lengths(_Frames(k), Paths(tree, k.structure))[0], q.shape[:-1])


def muscle_forces(k: Kinematics, activations, paths: Paths | None = None, frames: _Frames | None = None):
    """The muscles' tensions ``F (n, B)`` [N] at the activations ``(..., muscles)`` (clamped into ``[0, 1]`` here) and
    the kinematics ``k`` (with ``qd`` where a muscle's law reads ``dL/dt``)."""
    tree = k.tree
    paths = Paths(tree, k.structure) if paths is None else paths
    a = _batch_last(jnp.clip(jnp.broadcast_to(activations, k.R.shape[:-3] + activations.shape[-1:]), 0.0, 1.0), 1)
    velocity = any(mu.velocity_dependent for mu in tree.muscles)
    L = Ld = None
    if velocity or any(mu.length_dependent for mu in tree.muscles):
        frames = _Frames(k, velocity) if frames is None or (velocity and frames.v is None) else frames
        L, Ld = _lengths(frames, paths, velocity)
    groups = {}  # the muscles of each class, at once (Muscle.tensions)
    for i, mu in enumerate(tree.muscles):
        groups.setdefault(type(mu), []).append(i)
    parts, order = [], []
    for cls, rows in groups.items():
        idx = np.array(rows)
        pick = (lambda x: x) if len(groups) == 1 else (lambda x: x[idx])
        parts.append(cls.tensions([tree.muscles[i] for i in rows], pick(a), None if L is None else pick(L),
                                  None if Ld is None else pick(Ld)))
        order += rows
    F = parts[0] if len(parts) == 1 else jnp.concatenate(parts)
    return F if order == sorted(order) else F[np.argsort(order)]


def muscle_wrenches(k: Kinematics, activations):
    """The muscles' forces as spatial forces on the links ``(..., n, 6)`` (world-aligned, at the reference points):
    the ``external`` argument of :func:`~lagrange.rbda.rnea.rnea`, so that ``-rnea``'s share is ``-F dL/dq``;
    ``None`` where no segment joins two links."""
    paths = Paths(k.tree, k.structure)
    if not paths.moving.any():  # every muscle within one link (or on the world): no generalized force
        return None
    frames = _Frames(k, any(mu.velocity_dependent for mu in k.tree.muscles))
    F = muscle_forces(k, activations, paths, frames)
    n = paths.links
    per_link = [[] for _ in range(n + 1)]
    for a, b, rows, xs, xe in _pairs(frames, paths, moving_only=True):
        # dL/dx at each segment's two ends, weighted by its muscle's tension: the vjp of the segments' lengths with
        # the tensions as the cotangent; the forces -F dL/dx on the ends, their wrenches (x x f, f) summed per link
        Fs = jnp.asarray(_per_muscle(paths, rows).T, F.dtype) @ F  # each segment's tension (k, B)
        _, pull = jax.vjp(_segment_lengths, xs, xe)
        fs, fe = (-g for g in pull(Fs))
        per_link[a].append(jnp.sum(jnp.concatenate([_cross(xs, fs), fs], axis=1), axis=0))
        per_link[b].append(jnp.sum(jnp.concatenate([_cross(xe, fe), fe], axis=1), axis=0))
    zero = jnp.zeros((6, F.shape[-1]), F.dtype)
    w = jnp.stack([sum(parts[1:], parts[0]) if parts else zero for parts in per_link[:n]])  # (n, 6, B) about 0
    w = jnp.concatenate([w[:, :3] - _cross(frames.o[:n], w[:, 3:]), w[:, 3:]], axis=1)  # about the reference points
    return _batch_first(w, k.R.shape[:-3])


def _cross(a, b):
    """``a x b`` along axis 1 of ``(..., 3, B)`` arrays."""
    return jnp.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                      a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def muscle_torques(tree: Tree, q, qd, u):
    """The muscles' generalized forces ``-sum_m F_m dL_m/dq`` ``(..., nv)`` at the controls ``u`` (the motors', then
    the activations)."""
    k = Kinematics(tree, q, qd if any(mu.velocity_dependent for mu in tree.muscles) else None)
    w = muscle_wrenches(k, u[..., len(tree.motors):])
    return jnp.zeros(q.shape[:-1] + (tree.nv,), q.dtype) if w is None else k.project(k.up(w))
