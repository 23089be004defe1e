"""Lowering a planar :class:`lagrange.Tree` to the planar backend's :class:`~lagrange.planar.model.PlanarChain` while
tracing, as MJX derives its ``Model`` from an ``MjModel``.

The plane is the one normal to the hinges' common axis ``Y`` (:func:`lagrange.model.plane.normal`); its ``z`` is
against gravity's in-plane part (the world's ``z``, or ``x``, projected onto the plane when there is none or gravity is
traced) and ``x = Y x z``, so a tree in the world's x-z plane, a :class:`lagrange.chain.Chain` among them, has the
world's axes. One link per joint, in the tree's order:

- a link's frame is its body's frame as written, its origin the joint's anchor (a slide's: the body's origin, or the
  link before it in the same body); its ``offset`` the angle of its body's frame against its parent link's, less
  ``sense ref`` for a hinge whose ``ref`` is not 0 (a slide's ``ref`` moves its attach point instead);
- its ``attach`` point is its origin in the parent link's frame, left out where it is the parent's tip ``(0, -length)``;
  its ``length`` is its body's ``tip`` where that lies along the link (``(0, -length)`` in its frame), else 0;
- a hinge turning about ``-Y`` is a joint of ``sense = 1``, about ``+Y`` of ``sense = -1``; a slide's ``axis`` is its
  direction's angle against the parent link's frame;
- a body's mass, centre of mass and moment of inertia about ``Y`` go to its last joint's link, with the bodies welded to
  it (parallel axes in the plane); its contact points too; the joints' dampers, springs, ranges and motors are theirs.

For a chain built by :class:`lagrange.chain.Chain` every step is exact (body frames turned about ``y``, components
read, not rotated), so the lowered chain is the one its links describe: the same program as before trees and chains
were one model. Where a parameter is traced (a gradient with respect to the tree) it is carried through ``jax.numpy``,
and the terms whose zeros are then unknown stay in the program.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lagrange.model.checks import traced
from lagrange.model.link import Link
from lagrange.model.joints import Hinge
from lagrange.model.plane import normal, rotations
from lagrange.planar.model import PlanarChain
from lagrange.rbda.kinematics import body_frames_in_links, placements
from lagrange.rbda.structure import Structure

__all__ = ["lower"]

_SNAP = 1e-14  # entries of the static frame maps within round-off of 0 or +-1 are those (a turn about y is exact)


def _snap(x: np.ndarray) -> np.ndarray:
    x = np.array(x, float)
    for target in (0.0, 1.0, -1.0):
        x[np.abs(x - target) < _SNAP] = target
    return x


def _apply(P: np.ndarray, v):
    """``P v`` for a static ``P``: rows with one entry of +-1 read a component (exact, no product), others a sum."""
    if not traced(v):
        v = np.asarray(v, float)
    out = []
    for row in P:
        nz = np.flatnonzero(row)
        if len(nz) == 0:
            out.append(0.0)
        elif len(nz) == 1 and abs(row[nz[0]]) == 1.0:
            out.append(v[nz[0]] if row[nz[0]] > 0 else -v[nz[0]])
        else:
            out.append(sum(float(row[k]) * v[k] for k in nz))
    return out


def _sub(a, b):
    """``a - b`` for 3-vectors, skipping a concrete zero ``b`` (exact, no operation)."""
    if not traced(b) and not np.any(np.asarray(b)):
        return a
    if not traced(a, b):
        return np.asarray(a, float) - np.asarray(b, float)
    return jnp.asarray(a) - jnp.asarray(b)


def _is(x, value) -> bool:
    return not traced(x) and float(np.asarray(x)) == value


def _wrap(a: float) -> float:
    """``a`` in (-pi, pi], a negative zero as 0."""
    a = math.remainder(a, 2 * math.pi) + 0.0
    return math.pi if a == -math.pi else a


def _basis(tree, Y: np.ndarray):
    """The plane's ``(X, Z)``: ``Z`` against gravity's in-plane part where it is concrete and not zero, else the
    world's ``z`` (or ``x``) projected onto the plane; ``X = Y x Z``."""
    g = tree.gravity
    Z = None
    if not traced(g):
        g = np.asarray(g, float)
        g_in = g - (g @ Y) * Y
        if np.linalg.norm(g_in) > 0:
            Z = -g_in / np.linalg.norm(g_in)
    if Z is None:
        for w in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
            w_in = w - (w @ Y) * Y
            if np.linalg.norm(w_in) > 1e-6:
                Z = w_in / np.linalg.norm(w_in)
                break
    Z = _snap(Z)
    return _snap(np.cross(Y, Z)), Z


def _turn(quat, Y_parent: np.ndarray):
    """The angle by which a body's ``quat`` turns it in the plane against its parent's frame, where the quaternion's
    axis is the plane's normal (``Y_parent``: that normal in the parent's frame): ``2 atan2(v . -Y, w)``, read from the
    quaternion itself so that a chain's ``offset`` comes back as it was given; ``None`` for another turn."""
    w, v = quat[0], np.asarray(quat[1:], float)
    along = v @ Y_parent
    if np.linalg.norm(v - along * Y_parent) > 1e-12:
        return None
    return 2.0 * math.atan2(-along, w)


def _frame(theta: float | None, R: np.ndarray, X: np.ndarray, Z: np.ndarray):
    """A body's link-frame angle ``theta`` in the plane (given, or its ``x`` axis's, else its ``z`` axis's) and the
    static map ``P`` (2 x 3) from its frame's coordinates to the link frame's ``(x, z)`` (``x`` along ``e(theta)``,
    ``z`` along ``-d(theta)``)."""
    if theta is None:
        u, w = R[:, 0], R[:, 2]
        if math.hypot(u @ X, u @ Z) > 0.5:
            theta = math.atan2(u @ Z, u @ X)
        elif math.hypot(w @ X, w @ Z) > 0.5:
            theta = math.atan2(-(w @ X), w @ Z)
        else:
            v = R[:, 1]
            theta = math.atan2(v @ Z, v @ X)
    e = math.cos(theta) * X + math.sin(theta) * Z
    f = -math.sin(theta) * X + math.cos(theta) * Z
    return theta, _snap(np.stack([e @ R, f @ R]))


def _frames(tree, R_world, X, Y, Z):
    """Per body: ``(theta, P, turn)``: its link-frame angle and map (:func:`_frame`) and its turn against its parent's
    frame (``None`` where its quaternion leaves the plane: then the angles' difference)."""
    out = []
    for b, body in enumerate(tree.bodies):
        c = tree.parents[b]
        R_parent = np.eye(3) if c < 0 else R_world[c]
        turn = _turn(body.quat, _snap(R_parent.T @ Y))
        theta_parent = 0.0 if c < 0 else out[c][0]
        theta, P = _frame(None if turn is None else theta_parent + turn, R_world[b], X, Z)
        out.append((theta, P, turn))
    return out


def lower(tree) -> PlanarChain | None:
    """The :class:`~lagrange.planar.model.PlanarChain` of a planar tree (the module docstring says how), or ``None``
    where the tree is planar but the plane cannot carry it: a concrete gravity's in-plane part is along the plane's
    ``z`` (which follows it), but a traced gravity may have a part along its ``x`` (where
    :attr:`lagrange.Tree.gravity_support` does not rule that out), and a level ground need not be a line
    ``z = const`` of the plane; a tree without a plane (:attr:`lagrange.Tree.planar` false) has none; and the planar
    backends add motors only, listed in the order of their joints, not actuators whose force depends on the state
    (:class:`lagrange.model.tree.AffineActuator`, :class:`lagrange.Muscle`).

    Args:
        tree: a :class:`lagrange.Tree`, its concrete parameters as NumPy arrays or JAX arrays (both fold), traced ones
            as they are.
    """
    Y = normal(tree)
    if Y is None or tree.muscles or any(mo.state_dependent for mo in tree.motors):  # the chain carries motors only
        return None
    order = [mo.joint for mo in tree.motors]
    if order != sorted(order):  # the chain's u_k drives its k-th actuated joint: motors in joint order only
        return None
    Y = np.asarray(Y)
    X, Z = _basis(tree, Y)
    if traced(tree.gravity) and any(on and x != 0 for on, x in zip(tree.gravity_support, X)):
        return None  # gravity may have a part along the plane's x, which the chain (gravity along -z) cannot carry
    if tree.contact is not None and Z[2] != 1.0:  # the ground z = h must be the plane's line z = h
        return None
    st = Structure(tree)
    R_world = rotations(tree)
    frames = _frames(tree, R_world, X, Y, Z)
    R0, p0 = placements(st)
    carried = body_frames_in_links(st)
    leaves = [x for x in jax.tree_util.tree_leaves(tree) if eqx.is_inexact_array(x)]
    dtype = jnp.result_type(*leaves) if leaves else jax.dtypes.canonicalize_dtype(float)
    motors = {mo.joint: mo for mo in tree.motors}
    n = st.n
    origin, theta, length, attach = [None] * n, [0.0] * n, [0.0] * n, [None] * n
    links = []
    for i, j in enumerate(st.joints):
        b, parent = st.link_body[i], st.link_parent[i]
        body = tree.bodies[b]
        th, P, turn = frames[b]
        theta[i] = th
        last = i == n - 1 or st.link_body[i + 1] != b
        if isinstance(j, Hinge):
            origin[i] = j.pos
        else:
            origin[i] = np.zeros(3) if st.first[i] else origin[i - 1]
        theta_parent = 0.0 if parent < 0 else theta[parent]
        kw = {}
        # where the link's origin sits in its parent link's frame (the world's plane for a link of the world)
        if st.first[i]:
            here = p0[i] if _is_zero3(origin[i]) else _add(p0[i], _rotate(R0[i], origin[i]))
            if parent < 0:
                at = _apply(np.stack([X, Z]), here)
            else:
                at = _apply(frames[st.link_body[parent]][1], _sub(here, origin[parent]))
        else:
            at = _apply(P, _sub(origin[i], origin[i - 1]))
        # the link's turn against its parent link's frame: its body's, for the body's first joint
        above = -1 if parent < 0 else st.link_body[parent]  # the body whose frame the parent link's is
        rel = 0.0 if not st.first[i] else (turn if turn is not None and tree.parents[b] == above
                                           else th - theta_parent)
        if isinstance(j, Hinge):
            sense = 1 if (R_world[b] @ np.asarray(j.axis)) @ Y < 0 else -1
            kw["sense"] = sense
            offset = rel - sense * j.ref
        else:
            offset = rel
            d = _apply(P, np.asarray(j.axis))  # the slide's direction in the link's own frame
            kw["axis"] = _wrap(math.atan2(d[1], d[0]) + rel)
            if j.ref != 0.0:  # the link sits at q = 0 where the slide's ref left it: ref back along the slide
                at = [at[0] - j.ref * math.cos(kw["axis"]), at[1] - j.ref * math.sin(kw["axis"])]
        attach[i] = at
        if last:
            mass, com, moment = _rigid(tree, st, carried, b, Y, R_world)
            c = _apply(P, _sub(com, origin[i]))
            kw |= dict(com=_neg(c[1]), com_normal=c[0], inertia=moment)
            if body.tip is not None:
                t = _apply(P, _sub(body.tip, origin[i]))
                if _is(t[0], 0.0) and not traced(t[1]) and float(np.asarray(t[1])) <= 0:
                    length[i] = -float(np.asarray(t[1]))
            kw["contacts"] = [_contact(P, R, p, point, origin[i]) for b2, (R, p) in carried.items()
                              if st.body_link[b2] == i for point in tree.bodies[b2].contacts]
        else:
            mass, kw = 0.0, kw | dict(com=0.0, inertia=0.0)
        mo = motors.get(i)
        links.append(dict(joint="revolute" if isinstance(j, Hinge) else "prismatic", mass=mass, offset=_wrap(offset),
                          parent=parent, damping=j.damping, armature=j.armature, stiffness=j.stiffness,
                          springref=j.springref, range=j.range, gear=None if mo is None else mo.gear,
                          control_range=None if mo is None else mo.control_range, **kw))
    for i, lk in enumerate(links):  # at the parent's tip: no attach point of its own
        tip = (0.0, 0.0) if lk["parent"] < 0 else (0.0, -length[lk["parent"]])
        at = attach[i]
        if not (_is(at[0], tip[0]) and _is(at[1], tip[1])):
            lk["attach"] = (at[0], at[1])
    g = tree.gravity
    on = tree.gravity_support
    gravity = -float(np.asarray(g, float) @ Z) if not traced(g) else -sum(float(Z[k]) * g[k] for k in range(3)
                                                                          if Z[k] and on[k])
    return PlanarChain([Link(length=length[i], **lk) for i, lk in enumerate(links)], gravity,
                       contact=tree.contact if any(lk.get("contacts") for lk in links) else None,
                       limits=tree.limits, dtype=dtype)


def _is_zero3(v) -> bool:
    return not traced(v) and not np.any(np.asarray(v))


def _add(a, b):
    if not traced(a, b):
        return np.asarray(a, float) + np.asarray(b, float)
    return jnp.asarray(a) + jnp.asarray(b)


def _rotate(R, v):
    return R @ np.asarray(v, float) if not traced(R, v) else jnp.asarray(R) @ jnp.asarray(v)


def _neg(x):
    return -x if traced(x) else -float(np.asarray(x))


def _contact(P, R, p, point, origin):
    """A contact point ``(x, y, z, radius)`` of a body placed at ``(R, p)`` in its link's frame, as ``(x, z, radius)``
    in the link frame's plane coordinates."""
    c = np.asarray(p, float) + np.asarray(R, float) @ np.asarray(point[:3], float) - np.asarray(origin, float)
    x, z = _apply(P, c)
    return float(x), float(z), float(point[3])


def _rigid(tree, st, carried, b, Y, R_world):
    """Link of body ``b``: the mass, the centre of mass (in ``b``'s frame) and the moment of inertia about ``Y``
    through it of ``b`` and the bodies welded to it."""
    members = [(b2, R, p) for b2, (R, p) in carried.items() if st.body_link[b2] == st.body_link[b]]
    n_b = _snap(R_world[b].T @ Y)  # the plane's normal in b's frame
    if len(members) == 1:
        body = tree.bodies[b]
        return body.mass, body.com, _quadratic(n_b, body.inertia)
    # several bodies: their centres of mass in b's frame, combined by the parallel-axis theorem in the plane
    xs = [(tree.bodies[b2], _add(p, _rotate(R, tree.bodies[b2].com)), R) for b2, R, p in members]
    xp = jnp if traced(*(x for body, c, _ in xs for x in (body.mass, c, body.inertia))) else np
    m = sum(body.mass for body, _, _ in xs)
    c = sum(body.mass * c for body, c, _ in xs) / xp.where(m > 0, m, 1.0)
    moment = 0.0
    for body, x, R in xs:
        d = x - c
        d_in = d - (d @ n_b) * n_b
        moment = moment + _quadratic(_snap(R.T @ n_b), body.inertia) + body.mass * (d_in @ d_in)
    return m, c, moment


def _quadratic(n: np.ndarray, J):
    """``n^T J n`` for a static unit ``n``: one entry of ``J`` where ``n`` is an axis."""
    nz = np.flatnonzero(n)
    if len(nz) == 1:
        return J[nz[0], nz[0]]
    return sum(float(n[a] * n[c]) * J[a, c] for a in nz for c in nz)
