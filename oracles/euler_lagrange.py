"""The Euler-Lagrange equations derived literally: the oracle of the tests and the benchmarks' naive derivation.

This is the textbook derivation a reader can verify line by line: dense forward kinematics,
``L = T - V``, ``M = d2L/dqd2`` and ``C qd + T = d2L/dqd dq qd - dL/dq`` by JAX's dense
``hessian``/``jacfwd``, and ``jnp.linalg.solve``. It shares no code with
:mod:`lagrange.dynamics` except the :class:`~lagrange.chain.Chain` parameters, and is an order of
magnitude slower; an oracle, not for loops.

``tests/lagrange/test_dynamics.py``, ``planar/test_recursive.py`` and ``test_stability.py`` check ``lagrange``
against it; ``benchmarks/derivation_overhead.py`` times it as the "naive autodiff" derivation that ``lagrange``
replaces. All import it as ``oracles.euler_lagrange`` (from the repository root).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from lagrange.chain import Chain
from lagrange.model.tree import Tree
from lagrange.planar.lower import lower


def _planar(chain):
    """The planar parameters the derivation reads: a tree lowered to its links (its masses, lengths, centres of mass
    and inertias), once; the lowered chain as it is."""
    return lower(chain) if isinstance(chain, Tree) else chain


def _d(phi):
    return jnp.stack([jnp.sin(phi), -jnp.cos(phi)])


def _e(phi):
    return jnp.stack([jnp.cos(phi), jnp.sin(phi)])


def com_and_angles(chain: Chain, q):
    """Centres of mass ``(n, 2)`` and absolute link angles ``(n,)`` by plain forward kinematics: each link's joint at
    its attach point on its parent (``p_parent + x e - z d``, default the parent's tip ``l_parent d``)."""
    chain = _planar(chain)
    origins, phis, coms = [], [], []
    normal = jnp.zeros(chain.n, q.dtype) if chain.com_normal is None else chain.com_normal
    attach = dict(zip(chain.attached, [] if chain.attach is None else list(chain.attach)))
    for i, joint in enumerate(chain.joints):
        parent = chain.parents[i]
        p = jnp.zeros(2, q.dtype) if parent < 0 else origins[parent]
        base = jnp.zeros((), q.dtype) if parent < 0 else phis[parent]
        if i in attach:
            p = p + attach[i][0] * _e(base) - attach[i][1] * _d(base)
        elif parent >= 0:
            p = p + chain.length[parent] * _d(base)
        phi = base + chain.offsets[i]
        if joint == "revolute":
            phi = phi + chain.senses[i] * q[i]
        else:
            p = p + q[i] * _e(base + chain.axes[i])
        origins.append(p)
        phis.append(phi)
        coms.append(p + chain.com[i] * _d(phi) + normal[i] * _e(phi))
    return jnp.stack(coms), jnp.stack(phis)


def energy(chain: Chain, q, qd):
    """``(T, V)``: the kinetic energy from the centres of mass' velocities and the links' angular rates (one ``jvp``
    of the forward kinematics), and the potential ``sum_i m_i g z_i``."""
    chain = _planar(chain)

    def kin(q):
        return com_and_angles(chain, q)

    (c, phi), (v, w) = jax.jvp(kin, (q,), (qd,))
    T = 0.5 * jnp.sum(chain.mass * jnp.sum(v**2, axis=-1)) + 0.5 * jnp.sum(chain.inertia * w**2)
    if chain.armature is not None:
        T = T + 0.5 * jnp.sum(chain.armature * qd**2)
    g = 0.0 if chain.gravity is None else chain.gravity
    V = jnp.sum(chain.mass * g * c[:, 1])
    if chain.stiffness is not None:
        V = V + 0.5 * jnp.sum(chain.stiffness * (q - chain.springref) ** 2)
    return T, V


def lagrangian(chain: Chain, q, qd):
    chain = _planar(chain)
    T, V = energy(chain, q, qd)
    return T - V


def mass_matrix(chain: Chain, q):
    chain = _planar(chain)
    return jax.hessian(lagrangian, argnums=2)(chain, q, jnp.zeros_like(q))


def bias_forces(chain: Chain, q, qd):
    chain = _planar(chain)
    dL_dqd = jax.grad(lagrangian, argnums=2)
    mixed = jax.jacfwd(dL_dqd, argnums=1)(chain, q, qd)
    out = mixed @ qd - jax.grad(lagrangian, argnums=1)(chain, q, qd)
    if chain.damping is not None:
        out = out + chain.damping * qd
    return out


def accelerations(chain: Chain, M, bias, u=None):
    """``qdd`` solving ``M qdd = B u - bias`` for the mass matrix and bias forces given (``jnp.linalg.solve``)."""
    chain = _planar(chain)
    tau = jnp.zeros(bias.shape, bias.dtype)
    if u is not None and chain.m:
        tau = tau.at[jnp.array(chain.actuated)].add(chain.gear * u)
    return jnp.linalg.solve(M, tau - bias)


def forward_dynamics(chain: Chain, q, qd, u=None):
    chain = _planar(chain)
    return accelerations(chain, mass_matrix(chain, q), bias_forces(chain, q, qd), u)
