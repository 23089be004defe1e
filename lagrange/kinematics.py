"""Forward kinematics of a planar chain, as jets (values with their q-derivatives).

Each frame's origin and each centre of mass is a pair of :class:`~lagrange._jet.Jet` (x, z).
:func:`positions` and :func:`com_positions` read their values; the energy of chains shorter than
``lagrange.dynamics.RECURSIVE_MIN`` reads their velocities. Nothing here builds a dense Jacobian.
"""

from __future__ import annotations

from typing import NamedTuple

import math

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from lagrange import _scalar as s
from lagrange._jet import Jet, sincos
from lagrange._scalar import cos_sin
from lagrange.chain import Chain


class Frames(NamedTuple):
    """Kinematics of every link, as jets.

    ``origin[i]``: (x, z) of joint i; ``com[i]``: (x, z) of link i's centre of mass;
    ``tip``: (x, z) of the end of the last link; ``angle_rate[i]``: phi_i's time derivative
    (``None`` when velocities were not asked for); ``revolute_before[i]``: the revolute joints
    j <= i (the rows of phi_i's Jacobian, all ones).
    """

    origin: list
    com: list
    tip: tuple
    angle_rate: list
    revolute_before: list


def _vec_scale(v, c):
    return (v[0].scale(c), v[1].scale(c))


def _vec_add(a, b):
    return (a[0] + b[0], a[1] + b[1])


def _split(x, n: int):
    if x is None:
        return [0.0] * n
    return [x[..., i] for i in range(n)]


def frames(chain: Chain, q: Float[ArrayLike, "*batch n"], qd: Float[ArrayLike, "*batch n"] | None = None) -> Frames:
    """Jets of every joint origin and centre of mass, at joint coordinates ``q`` [rad or m] and velocities ``qd``
    [rad/s or m/s] of shape ``(*batch, n)``; positions in m. ``qd=None`` drops all velocity terms."""
    n = chain.n
    qs = _split(q, n)
    qds = _split(qd, n)
    phi = Jet.const(0.0)
    sin_phi, cos_phi = Jet.const(0.0), Jet.const(1.0)
    p = (Jet.const(0.0), Jet.const(0.0))
    length_prev = 0.0
    off = chain.frame_offsets()
    off_prev = 0.0
    normal = chain.com_normal
    origin, com, rates, rev = [], [], [], []
    revolute: list[int] = []
    rate = 0.0
    for i, joint in enumerate(chain.joints):
        # phi is the sum of the revolute q's; link i's frame is at phi + off[i]
        if i > 0:
            p = _vec_add(p, _along(sin_phi, cos_phi, off_prev, length_prev, None))
        qi = Jet.coordinate(i, qs[i], qds[i])
        if joint == "revolute":
            phi = phi + qi
            revolute = revolute + [i]
            rate = s.add(rate, qds[i])
            sin_phi, cos_phi = sincos(phi)
        else:  # prismatic: slide along e(phi_{i-1} + axis)
            a = chain.axes[i] + off_prev
            if a == 0.0:
                ex, ez = cos_phi, sin_phi
            else:  # e(phi + a) = cos(a) e(phi) + sin(a) e'(phi), e' = (-sin, cos)
                ca, sa = cos_sin(a)
                ex = cos_phi.scale(ca) - sin_phi.scale(sa)
                ez = sin_phi.scale(ca) + cos_phi.scale(sa)
            p = _vec_add(p, (ex * qi, ez * qi))
        origin.append(p)
        com.append(_vec_add(p, _along(sin_phi, cos_phi, off[i], chain.com[i], None if normal is None else normal[i])))
        rates.append(rate if qd is not None else None)
        rev.append(tuple(revolute))
        length_prev, off_prev = chain.length[i], off[i]
    tip = _vec_add(p, _along(sin_phi, cos_phi, off_prev, length_prev, None))
    return Frames(origin, com, tip, rates, rev)


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


def positions(chain: Chain, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n+1 2"]:
    """Joint origins and the tip [m] as (x, z) rows, shape ``(*batch, n + 1, 2)``, at joint coordinates ``q``
    [rad or m] of shape ``(*batch, n)``; for plotting."""
    f = frames(chain, q)
    pts = f.origin + [f.tip]
    like = q[..., 0]
    return jnp.stack(
        [jnp.stack([s.as_array(pt[0].v, like), s.as_array(pt[1].v, like)], axis=-1) for pt in pts],
        axis=-2,
    )


def com_positions(chain: Chain, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n 2"]:
    """Centres of mass [m] as (x, z) rows, shape ``(*batch, n, 2)``, at joint coordinates ``q`` [rad or m] of shape
    ``(*batch, n)``."""
    f = frames(chain, q)
    like = q[..., 0]
    return jnp.stack(
        [jnp.stack([s.as_array(c[0].v, like), s.as_array(c[1].v, like)], axis=-1) for c in f.com],
        axis=-2,
    )
