"""Equations of motion ``M(q) qdd + C(q, qd) qd + T(q) + D qd = B u``, derived by autodiff.

The kinetic energy of a planar chain is ``T = 1/2 sum_i (m_i |J_i qd|^2 + I_i (s_i qd)^2)
+ 1/2 sum_j a_j qd_j^2``, with ``J_i`` the Jacobian of link i's centre of mass and ``s_i`` the
0/1 row of the revolute joints before it. Lagrange's equations then give

- ``M = d2T/dqd2 = sum_i m_i J_i^T J_i + I_i s_i^T s_i + diag(armature)``,
- ``C qd = sum_i m_i J_i^T (dJ_i/dt) qd`` (the velocity-product acceleration of each centre of
  mass, pulled back to the joints; the planar rotation terms have none),
- ``T(q) = dV/dq = sum_i m_i g J_i^T e_z``.

Both ``J_i`` and ``(dJ_i/dt) qd`` are differentiated at trace time from the forward kinematics
(:mod:`lagrange._unitvec`; the sparse jets of :mod:`lagrange._jet` for longer chains), simplified at trace time, so the compiled
program contains only the terms the chain has. :mod:`lagrange.euler_lagrange` derives the same
quantities literally (Hessians of the Lagrangian) and serves as the check.

Chains of ``RECURSIVE_MIN`` or more links use the recursive algorithms of
:mod:`lagrange.recursive` instead (ABA, RNEA, CRBA as scans over the links), whose work grows
like n rather than n^3.

All functions are pure, accept leading batch dimensions on ``q``/``qd``/``u`` and are safe
under ``jit``, ``vmap`` and ``grad``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from lagrange import _scalar as s
from lagrange import _unitvec
from lagrange import recursive
from lagrange._linalg import solve_spd, to_array
from lagrange.chain import Chain
from lagrange.kinematics import frames


def _as_constant(x):
    if isinstance(x, jax.Array) and not isinstance(x, jax.core.Tracer) and x.is_fully_addressable:
        return np.asarray(x)
    return x


def _folded(chain: Chain) -> Chain:
    """``chain`` with its concrete parameters as NumPy arrays, so that their products with each other are computed
    while tracing and reach XLA as literals. A chain closed over by a jitted function has concrete parameters, but
    XLA receives them as run-time operands of the time-stepping loop: it does not fold them, and on the CPU they can
    cost the fused step its vectorization (``python -m research.xla_vectorization``: the cartpole's
    closed form 1.7-1.9x slower with its constants as arrays). Parameters being differentiated or vmapped are
    tracers and stay as they are."""
    return jax.tree_util.tree_map(_as_constant, chain)


def _check(chain: Chain, name: str, x, size: int):
    shape = jnp.shape(x)
    if len(shape) == 0 or shape[-1] != size:
        what = " (the chain has no actuated joint: pass u=None)" if name == "u" and size == 0 else ""
        raise ValueError(f"{name} must have shape (..., {size}) for this chain{what}, got {shape}")


def _mass_entries(chain: Chain, f) -> list[list]:
    """Lower triangle of the translational part of M, ``sum_i m_i J_i^T J_i``, from jets."""
    n = chain.n
    M = [[0.0] * n for _ in range(n)]
    for i, (cx, cz) in enumerate(f.com):
        m = chain.mass[i]
        cols = sorted(set(cx.g) | set(cz.g))
        for a, j in enumerate(cols):
            for k in cols[: a + 1]:
                jj, kk = max(j, k), min(j, k)
                dot = s.add(
                    s.mul(cx.g.get(j, 0.0), cx.g.get(k, 0.0)), s.mul(cz.g.get(j, 0.0), cz.g.get(k, 0.0))
                )
                M[jj][kk] = s.add(M[jj][kk], s.mul(m, dot))
    return M


def _add_rotational(chain: Chain, M: list[list]) -> list[list]:
    """Add ``sum_i I_i s_i^T s_i + diag(armature)`` (s_i: the revolute joints up to link i) to M."""
    revolute: list[int] = []
    for i, joint in enumerate(chain.joints):
        if joint == "revolute":
            revolute.append(i)
        for a, j in enumerate(revolute):
            for k in revolute[: a + 1]:
                M[j][k] = s.add(M[j][k], chain.inertia[i])
    for j in chain.armatured:
        M[j][j] = s.add(M[j][j], chain.armature[j])
    return M


def _generalized(chain: Chain, f, *, velocity: bool, gravity: bool) -> list:
    """sum_i J_i^T F_i for the force F_i = m_i (a_i + g e_z) on each centre of mass."""
    n = chain.n
    out = [0.0] * n
    g = chain.gravity if (gravity and chain.gravity is not None) else 0.0
    for i, (cx, cz) in enumerate(f.com):
        m = chain.mass[i]
        fx = s.mul(m, cx.a) if velocity else 0.0
        fz = s.mul(m, s.add(cz.a if velocity else 0.0, g))
        for j in set(cx.g) | set(cz.g):
            out[j] = s.add(out[j], s.add(s.mul(cx.g.get(j, 0.0), fx), s.mul(cz.g.get(j, 0.0), fz)))
    return out


UNITVEC_MAX = 4
"""Chains of up to this many links use the relative-angle formulation of :mod:`lagrange._unitvec`
(fewest operations for short chains); longer ones use the jets of :mod:`lagrange._jet`
(O(n) transcendentals). With the default ``RECURSIVE_MIN`` the jets serve only chains of
``RECURSIVE_MIN`` or more links when that switch is raised (the recursive path's tests compare
against them). Measured on n-link pendulums, compiled arithmetic ops relative-angle /
jets: n=2 38/68, n=3 131/160, n=4 458/494, n=5 1110/950, n=6 2390/1648."""


def _terms(chain: Chain, q, qd, *, mass: bool, velocity: bool, gravity: bool):
    """(lower triangle of M or None, generalized velocity-product + gravity forces or None)."""
    if chain.n <= UNITVEC_MAX:
        absolute = _unitvec.plan(chain, mass=mass, velocity=velocity, gravity=gravity)
        geom = _unitvec.Geometry(chain, q, qd if velocity else None, absolute)
        M = _add_rotational(chain, _unitvec.mass_entries(chain, geom)) if mass else None
        f = _unitvec.generalized_forces(chain, geom, velocity=velocity, gravity=gravity) if (velocity or gravity) else None
    else:
        fr = frames(chain, q, qd if velocity else None)
        M = _add_rotational(chain, _mass_entries(chain, fr)) if mass else None
        f = _generalized(chain, fr, velocity=velocity, gravity=gravity) if (velocity or gravity) else None
    if f is not None and velocity and chain.damping is not None:
        for j in chain.damped:
            f[j] = s.add(f[j], s.mul(chain.damping[j], qd[..., j]))
    return M, f


RECURSIVE_MIN = 5
"""Chains of at least this many links use the recursive algorithms of :mod:`lagrange.recursive`
(ABA for ``forward_dynamics``, CRBA for ``mass_matrix``, RNEA for the forces,
``inverse_dynamics`` and ``energy``): O(n) work (O(n^2) for M) and a compiled program whose size
does not depend on n. Shorter chains keep the unrolled derivations above.

Measured on n-link pendulums (every joint actuated), semi-implicit Euler rollouts of 20 steps,
float64, one CPU core of a busy 2-core machine, microseconds per env-step, unrolled / recursive:

- n = 4, batch 1: forward 1.4 / 3.7-5.2, gradient 5.2 / 19; batch 1024: forward 0.74 / 0.42,
  gradient 2.9 / 1.0-2.0.
- n = 5, batch 1: forward 1.8 / 3.7-4.2, gradient 452 / 10-17; batch 1024: forward 1.6 / 0.6-0.7,
  gradient 814 / 1.6-2.7.
- n = 6, batch 1: forward 4.4 / ~5, gradient 4500 / 17; batch 1024: gradient -- / 3.2.

The unrolled path's reverse mode breaks down from n = 5 (the jets of :mod:`lagrange._jet`; its
gradient also takes minutes to compile from n = 7), while at n <= 4 (the relative-angle
formulation) it is the faster choice at batch 1, where each of the recursive path's scans pays a
per-link loop overhead of ~0.1-0.5 us. Hence 5."""


def _recursive(chain: Chain) -> bool:
    return chain.n >= RECURSIVE_MIN


def _stack(xs, like):
    return jnp.stack([s.as_array(x, like) for x in xs], axis=-1)


def mass_matrix(chain: Chain, q) -> jnp.ndarray:
    """Mass matrix ``M(q)``, shape ``(..., n, n)``, symmetric positive definite."""
    _check(chain, "q", q, chain.n)
    chain = _folded(chain)
    if _recursive(chain):
        return recursive.mass_matrix(chain, q)
    M, _ = _terms(chain, q, None, mass=True, velocity=False, gravity=False)
    return to_array(M, q[..., 0], symmetric=True)


def bias_forces(chain: Chain, q, qd) -> jnp.ndarray:
    """``C(q, qd) qd + T(q) + D qd``, shape ``(..., n)``: what the joints must supply at ``qdd = 0``."""
    _check(chain, "q", q, chain.n)
    _check(chain, "qd", qd, chain.n)
    chain = _folded(chain)
    if _recursive(chain):
        return recursive.bias_forces(chain, q, qd)
    _, f = _terms(chain, q, qd, mass=False, velocity=True, gravity=True)
    return _stack(f, q[..., 0])


def gravity_forces(chain: Chain, q) -> jnp.ndarray:
    """``T(q) = dV/dq``, shape ``(..., n)``."""
    _check(chain, "q", q, chain.n)
    chain = _folded(chain)
    if _recursive(chain):
        return recursive.gravity_forces(chain, q)
    _, f = _terms(chain, q, None, mass=False, velocity=False, gravity=True)
    return _stack(f, q[..., 0])


def actuation_matrix(chain: Chain) -> jnp.ndarray:
    """``B``, shape ``(n, m)``: ``B[actuated[k], k] = gear[k]``."""
    B = jnp.zeros((chain.n, chain.m), dtype=chain.mass.dtype)
    for k, j in enumerate(chain.actuated):
        B = B.at[j, k].set(chain.gear[k])
    return B


def _actuation(chain: Chain, u) -> list:
    out = [0.0] * chain.n
    _check(chain, "u", u, chain.m)
    if chain.m:
        for k, j in enumerate(chain.actuated):
            out[j] = s.mul(chain.gear[k], u[..., k])
    return out


def forward_dynamics(chain: Chain, q, qd, u=None) -> jnp.ndarray:
    """Joint accelerations ``qdd = M^-1 (B u - C qd - T - D qd)``, shape ``(..., n)``.

    ``u`` has shape ``(..., m)``; it may be ``None`` (no control) or omitted for an unactuated chain.
    """
    return _forward(chain, q, qd, u)


def _forward(chain: Chain, q, qd, u=None, implicit_damping_dt=None) -> jnp.ndarray:
    """``forward_dynamics``; with ``implicit_damping_dt = h`` it solves with ``M + h diag(damping)``."""
    _check(chain, "q", q, chain.n)
    _check(chain, "qd", qd, chain.n)
    chain = _folded(chain)
    if _recursive(chain):
        if u is not None:
            _check(chain, "u", u, chain.m)
        return recursive.forward_dynamics(chain, q, qd, u, implicit_damping_dt=implicit_damping_dt)
    M, bias = _terms(chain, q, qd, mass=True, velocity=True, gravity=True)
    tau = _actuation(chain, u) if u is not None else [0.0] * chain.n
    # an unactuated joint's -bias keeps its sign symbolic (folded into the solve, see _scalar.negated)
    rhs = [s.negated(b) if s.is_zero(t) else s.sub(t, b) for t, b in zip(tau, bias)]
    like = q[..., 0] if jnp.ndim(q) >= jnp.ndim(qd) else qd[..., 0]
    if implicit_damping_dt is not None and chain.damping is not None:
        for j in chain.damped:
            M[j][j] = s.add(M[j][j], s.mul(implicit_damping_dt, chain.damping[j]))
    qdd = solve_spd(M, rhs, like)
    return _stack(qdd, like)


def inverse_dynamics(chain: Chain, q, qd, qdd) -> jnp.ndarray:
    """Generalized forces ``M qdd + C qd + T + D qd`` that produce ``qdd``, shape ``(..., n)``."""
    _check(chain, "qdd", qdd, chain.n)
    if _recursive(chain):
        _check(chain, "q", q, chain.n)
        _check(chain, "qd", qd, chain.n)
        return recursive.inverse_dynamics(chain, q, qd, qdd)
    return jnp.einsum("...ij,...j->...i", mass_matrix(chain, q), qdd) + bias_forces(chain, q, qd)


def energy(chain: Chain, q, qd) -> tuple[jnp.ndarray, jnp.ndarray]:
    """``(kinetic, potential)`` energy [J]; potential is zero with the chain's origin at z = 0."""
    _check(chain, "q", q, chain.n)
    _check(chain, "qd", qd, chain.n)
    if _recursive(chain):
        return recursive.energy(chain, q, qd)
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
    return s.as_array(kin, like), s.as_array(pot, like)
