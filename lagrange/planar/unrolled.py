"""The unrolled derivation behind :mod:`lagrange.dynamics` for chains shorter than ``RECURSIVE_MIN`` links.

Call :mod:`lagrange.dynamics`: it checks the arguments and picks this derivation or the recursive algorithms
(:mod:`lagrange.planar.recursive`) by the chain's size. Here ``J_i`` and ``(dJ_i/dt) qd`` are differentiated at trace
time from the forward kinematics written as sums of unit vectors (:mod:`lagrange.planar.unitvec`), simplified at trace
time, so the compiled program contains only the terms the chain has, and ``M qdd = rhs`` is solved unrolled over scalars
(:func:`lagrange.math.scalar.solve_spd`). For the acrobot this is the closed form a person writes by hand.

Every function takes a chain whose concrete parameters are NumPy arrays (``lagrange.dynamics`` folds them) and
``q``/``qd``/``u`` of shape ``(*batch, n)`` (``(*batch, m)``), and returns what the function of the same name in
:mod:`lagrange.dynamics` returns.
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import ClassVar

import jax.numpy as jnp

from lagrange.math import scalar as s
from lagrange.planar import unitvec as _unitvec
from lagrange.forces import clamp_controls
from lagrange.planar.model import WORLD, AbstractPlanar, PlanarChain
from lagrange.planar.frames import frames

__all__ = ["Unrolled", "bias_forces", "energy", "forward_dynamics", "gravity_forces", "inverse_dynamics",
           "mass_matrix"]


def _add_rotational(chain: PlanarChain, M: list[list]) -> list[list]:
    """Add ``sum_i I_i s_i^T s_i + diag(armature)`` (s_i: the revolute joints on link i's path) to M."""
    revolute: list[tuple[int, ...]] = []
    for i, joint in enumerate(chain.joints):
        p = chain.parents[i]
        path = () if p == WORLD else revolute[p]
        path = path + (i,) if joint == "revolute" else path
        revolute.append(path)
        for a, j in enumerate(path):
            for k in path[: a + 1]:  # d phi_i / d q_j = sense_j
                term = chain.inertia[i]
                M[j][k] = s.add(M[j][k], term if chain.senses[j] == chain.senses[k] else s.negated(term))
    for j in chain.armatured:
        M[j][j] = s.add(M[j][j], chain.armature[j])
    return M


def _terms(chain: PlanarChain, q, qd, *, mass: bool, velocity: bool, gravity: bool):
    """(lower triangle of M or None, generalized velocity-product + gravity forces or None), by the relative-angle
    formulation of :mod:`lagrange.planar.unitvec`."""
    absolute = _unitvec.plan(chain, mass=mass, velocity=velocity, gravity=gravity)
    geom = _unitvec.Geometry(chain, q, qd if velocity else None, absolute)
    M = _add_rotational(chain, _unitvec.mass_entries(chain, geom)) if mass else None
    f = _unitvec.generalized_forces(chain, geom, velocity=velocity, gravity=gravity) if (velocity or gravity) else None
    if f is not None and velocity and chain.damping is not None:
        for j in chain.damped:
            f[j] = s.add(f[j], s.mul(chain.damping[j], qd[..., j]))
    if f is not None and velocity and chain.stiffness is not None:  # the joint springs, with the damping
        for j in chain.sprung:
            f[j] = s.add(f[j], s.mul(chain.stiffness[j], s.sub(q[..., j], chain.springref[j])))
    if f is not None and velocity and chain.limits is not None:  # the limits' penalty, a force the joints receive
        tau = chain.limits.forces(q[..., list(chain.limited)], qd[..., list(chain.limited)], chain.ranges[:, 0],
                                  chain.ranges[:, 1])
        for k, j in enumerate(chain.limited):
            f[j] = s.sub(f[j], tau[..., k])
    if f is not None and velocity and chain.contact is not None:
        for j, tau in enumerate(_contact_forces(chain, q, qd)):
            f[j] = s.sub(f[j], tau)
    return M, f


def _spots(chain: PlanarChain, q, qd):
    """Per contact point: its link, radius, and the jets (x, z) of the point (:func:`lagrange.kinematics.frames`)."""
    points = [(i, p[0], p[1]) for i, p in zip(chain.contact_links, chain.contact_points)]
    f = frames(chain, q, qd, points=points)
    return f, [(i, p[2], xz) for i, p, xz in zip(chain.contact_links, chain.contact_points, f.points)]


def _contact_forces(chain: PlanarChain, q, qd) -> list:
    """``J_s^T (ft, fn)`` summed over the contact points, per joint (scalars): the force at each point's lowest spot
    ``s = p - r e_z``, whose material velocity is the point's plus ``w perp(s - p) = (w r, 0)``."""
    f, spots = _spots(chain, q, qd)
    like = q[..., 0]
    out = [0.0] * chain.n
    for link, r, (x, z) in spots:
        w = s.as_array(f.angle_rate[link], like)
        depth = chain.contact.ground - (s.as_array(z.v, like) - r)
        fn, ft = chain.contact.forces(depth, s.as_array(z.vd, like), s.as_array(x.vd, like) + w * r)
        for j in set(x.g) | set(z.g):
            out[j] = s.add(out[j], s.add(s.mul(x.g.get(j, 0.0), ft), s.mul(z.g.get(j, 0.0), fn)))
        for j in f.revolute_before[link]:  # the moment r ft of the force at s about p, d phi / d q_j = sense_j
            out[j] = s.add(out[j], s.mul(float(chain.senses[j]) * r, ft))
    return out


def _stack(xs, like):
    return jnp.stack([s.as_array(x, like) for x in xs], axis=-1)


def mass_matrix(chain: PlanarChain, q):
    """The mass matrix ``M(q)``, written out entry by entry.

    Arguments and result as :func:`lagrange.dynamics.mass_matrix`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    M, _ = _terms(chain, q, None, mass=True, velocity=False, gravity=False)
    return s.to_array(M, q[..., 0], symmetric=True)


def bias_forces(chain: PlanarChain, q, qd):
    """The bias forces, written out joint by joint.

    Arguments and result as :func:`lagrange.dynamics.bias_forces`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    _, f = _terms(chain, q, qd, mass=False, velocity=True, gravity=True)
    return _stack(f, q[..., 0])


def gravity_forces(chain: PlanarChain, q):
    """The generalized gravity forces, written out joint by joint.

    Arguments and result as :func:`lagrange.dynamics.gravity_forces`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    _, f = _terms(chain, q, None, mass=False, velocity=False, gravity=True)
    return _stack(f, q[..., 0])


def _actuation(chain: PlanarChain, u) -> list:
    """``B u`` as a list of scalars (a constant 0 on every unactuated joint)."""
    out = [0.0] * chain.n
    if chain.m:
        u = clamp_controls(chain, u)
        for k, j in enumerate(chain.actuated):
            out[j] = s.mul(chain.gear[k], u[..., k])
    return out


def forward_dynamics(chain: PlanarChain, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
    """Joint accelerations ``qdd = M^-1 (B u - bias)``, ``M qdd = rhs`` solved unrolled over scalars.

    Arguments and result as :func:`lagrange.dynamics.forward_dynamics`'s, for a chain that function has prepared
    (its concrete parameters folded to NumPy arrays); nothing is checked here. ``pivots=True`` also returns
    ``singular`` (shape ``batch``), true where a pivot of the factorisation of ``M`` (the determinant for n <= 3)
    is not positive or not finite (:func:`lagrange.dynamics.forward_dynamics_and_pivots`).
    """
    M, bias = _terms(chain, q, qd, mass=True, velocity=True, gravity=True)
    tau = _actuation(chain, u) if u is not None else [0.0] * chain.n
    # an unactuated joint's -bias keeps its sign symbolic (folded into the solve, see _scalar.negated)
    rhs = [s.negated(b) if s.is_zero(t) else s.sub(t, b) for t, b in zip(tau, bias)]
    like = q[..., 0] if jnp.ndim(q) >= jnp.ndim(qd) else qd[..., 0]
    if implicit_damping_dt is not None and chain.damping is not None:
        for j in chain.damped:
            M[j][j] = s.add(M[j][j], s.mul(implicit_damping_dt, chain.damping[j]))
    if not pivots:
        return _stack(s.solve_spd(M, rhs, like), like)
    qdd, p = s.solve_spd(M, rhs, like, pivots=True)
    p = jnp.stack(jnp.broadcast_arrays(*(s.as_array(x, like) for x in p)), axis=-1)
    return _stack(qdd, like), jnp.any(~((p > 0) & jnp.isfinite(p)), axis=-1)


def energy(chain: PlanarChain, q, qd):
    """The kinetic and potential energy, from the jets of :func:`lagrange.kinematics.frames`.

    Arguments and result as :func:`lagrange.dynamics.energy`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    f = frames(chain, q, qd)
    like = q[..., 0]
    kin = 0.0
    pot = 0.0
    for i, (cx, cz) in enumerate(f.com):
        v2 = s.add(s.mul(cx.vd, cx.vd), s.mul(cz.vd, cz.vd))
        kin = s.add(kin, s.mul(0.5 * chain.mass[i], v2))
        w = f.angle_rate[i]
        kin = s.add(kin, s.mul(0.5 * chain.inertia[i], s.mul(w, w)))
        if chain.gravity is not None:
            pot = s.add(pot, s.mul(chain.mass[i] * chain.gravity, cz.v))
    for j in chain.armatured:
        kin = s.add(kin, s.mul(0.5 * chain.armature[j], s.mul(qd[..., j], qd[..., j])))
    for j in chain.sprung:
        stretch = s.sub(q[..., j], chain.springref[j])
        pot = s.add(pot, s.mul(0.5 * chain.stiffness[j], s.mul(stretch, stretch)))
    if chain.limits is not None:
        v = chain.limits.energy(q[..., list(chain.limited)], chain.ranges[:, 0], chain.ranges[:, 1])
        pot = s.add(pot, jnp.sum(v, axis=-1))
    if chain.contact is not None:
        for _, r, (_, z) in _spots(chain, q, None)[1]:
            pot = s.add(pot, chain.contact.energy(chain.contact.ground - (s.as_array(z.v, like) - r)))
    return s.as_array(kin, like), s.as_array(pot, like)


def inverse_dynamics(chain: PlanarChain, q, qd, qdd):
    """``M qdd + bias``: arguments and result as :func:`lagrange.dynamics.inverse_dynamics`'s, for a prepared chain."""
    return jnp.einsum("...ij,...j->...i", mass_matrix(chain, q), qdd) + bias_forces(chain, q, qd)


class Unrolled(AbstractPlanar):
    """The unrolled relative-angle derivation (this module): every entry written out, constants folded while
    tracing; the closed form a person writes by hand for a short chain."""

    derivation: ClassVar[ModuleType] = sys.modules[__name__]
