"""Forward kinematics of a planar chain, as jets (values with their q-derivatives), for the unrolled derivation.

Each frame's origin and each centre of mass is a pair of :class:`~lagrange.planar.jet.Jet` (x, z); the energy and the
contact forces of chains shorter than ``lagrange.dynamics.RECURSIVE_MIN`` read their values and velocities. Nothing
here builds a dense Jacobian.
"""

from __future__ import annotations

from typing import NamedTuple


import jax.numpy as jnp
from jaxtyping import ArrayLike, Float

from lagrange.math import scalar as s
from lagrange.planar.jet import Jet, sincos
from lagrange.math.scalar import cos_sin
from lagrange.planar.model import WORLD, PlanarChain


class Frames(NamedTuple):
    """Kinematics of every link, as jets.

    ``origin[i]``: (x, z) of joint i; ``com[i]``: (x, z) of link i's centre of mass;
    ``tip``: (x, z) of the end of the last link; ``angle_rate[i]``: phi_i's time derivative
    (``None`` when velocities were not asked for); ``revolute_before[i]``: the revolute joints on the path
    from the world to link i, i included (the rows of phi_i's Jacobian, each joint's ``sense``); ``tips[i]``: (x, z) of
    the end of link i (``length`` along its direction from its joint), or ``None`` when not asked for; ``points[k]``:
    (x, z) of the ``k``-th point asked for.
    """

    origin: list
    com: list
    tip: tuple
    angle_rate: list
    revolute_before: list
    tips: list
    points: list


def _vec_scale(v, c):
    return (v[0].scale(c), v[1].scale(c))


def _vec_add(a, b):
    return (a[0] + b[0], a[1] + b[1])


def _split(x, n: int):
    if x is None:
        return [0.0] * n
    return [x[..., i] for i in range(n)]


def frames(chain: PlanarChain, q: Float[ArrayLike, "*batch n"], qd: Float[ArrayLike, "*batch n"] | None = None, *,
           tips: bool = False, points=()) -> Frames:
    """Jets of every joint origin and centre of mass, at joint coordinates ``q`` [rad or m] and velocities ``qd``
    [rad/s or m/s] of shape ``(*batch, n)``; positions in m. ``qd=None`` drops all velocity terms; ``tips=True`` adds
    the end of every link (``Frames.tips``; else ``None``); ``points``, a sequence of ``(link, x, z)`` (a point
    ``(x, z)`` of the link's frame), adds their jets (``Frames.points``)."""
    n = chain.n
    for name, x in (("q", q), ("qd", qd)):
        if x is not None and (jnp.ndim(x) == 0 or jnp.shape(x)[-1] != n):
            raise ValueError(f"{name} must have shape (..., {n}) for this chain, got {jnp.shape(x)}")
    qs = _split(q, n)
    qds = _split(qd, n)
    off = chain.frame_offsets()
    normal = chain.com_normal
    attach = {i: k for k, i in enumerate(chain.attached)}
    world = (Jet.const(0.0), Jet.const(0.0), Jet.const(1.0), (Jet.const(0.0), Jet.const(0.0)), 0.0, ())
    state = []  # per link: phi (the sum of the revolute q's on its path), sin, cos, origin, angle rate, revolute joints
    origin, com, rates, rev = [], [], [], []
    for i, joint in enumerate(chain.joints):
        parent = chain.parents[i]
        phi, sin_phi, cos_phi, p, rate, revolute = world if parent == WORLD else state[parent]
        off_prev = 0.0 if parent == WORLD else off[parent]
        # link i's joint sits at its attach point on the parent (default: the parent's tip); frames at phi + off
        if i in attach:
            x, z = chain.attach[attach[i]][0], chain.attach[attach[i]][1]
            p = _vec_add(p, _along(sin_phi, cos_phi, off_prev, s.neg(z), x))
        elif parent != WORLD:
            p = _vec_add(p, _along(sin_phi, cos_phi, off_prev, chain.length[parent], None))
        qi = Jet.coordinate(i, qs[i], qds[i])
        if joint == "revolute":
            phi = phi + qi if chain.senses[i] > 0 else phi - qi
            revolute = revolute + (i,)
            rate = s.add(rate, qds[i]) if chain.senses[i] > 0 else s.sub(rate, qds[i])
            sin_phi, cos_phi = sincos(phi)
        else:  # prismatic: slide along e(phi_parent + axis)
            a = chain.axes[i] + off_prev
            if a == 0.0:
                ex, ez = cos_phi, sin_phi
            else:  # e(phi + a) = cos(a) e(phi) + sin(a) e'(phi), e' = (-sin, cos)
                ca, sa = cos_sin(a)
                ex = cos_phi.scale(ca) - sin_phi.scale(sa)
                ez = sin_phi.scale(ca) + cos_phi.scale(sa)
            p = _vec_add(p, (ex * qi, ez * qi))
        state.append((phi, sin_phi, cos_phi, p, rate, revolute))
        origin.append(p)
        com.append(_vec_add(p, _along(sin_phi, cos_phi, off[i], chain.com[i], None if normal is None else normal[i])))
        rates.append(rate if qd is not None else None)
        rev.append(revolute)
    ends = [_vec_add(origin[i], _along(state[i][1], state[i][2], off[i], chain.length[i], None))
            for i in (range(n) if tips else [n - 1])]
    # a point (x, z) of link i's frame is at p_i + x e(phi + off) - z d(phi + off)
    marked = [_vec_add(origin[i], _along(state[i][1], state[i][2], off[i], s.neg(z), x)) for i, x, z in points]
    return Frames(origin, com, ends[-1], rates, rev, ends if tips else None, marked)


def _along(sin_phi, cos_phi, off: float, c_d, c_e):
    """``c_d d(phi + off) + c_e e(phi + off)`` as a pair of jets, with ``d = (sin, -cos)``, ``e = (cos, sin)``
    (``c_e = None``: none)."""
    if off != 0.0:
        co, so = cos_sin(off)
        c_d, c_e = (
            s.sub(s.mul(co, c_d), s.mul(so, 0.0 if c_e is None else c_e)),
            s.add(s.mul(so, c_d), s.mul(co, 0.0 if c_e is None else c_e)),
        )
    out = _vec_scale((sin_phi, -cos_phi), c_d)
    if c_e is not None and not s.is_zero(c_e):
        out = _vec_add(out, _vec_scale((cos_phi, sin_phi), c_e))
    return out
