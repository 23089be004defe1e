"""Equations of motion ``M(q) qdd + C(q, qd) qd + T(q) + D qd + K (q - q_ref) = B u + tau_limits + sum_s J_s^T f_s``.

The kinetic energy of a planar chain or tree is ``T = 1/2 sum_i (m_i |J_i qd|^2 + I_i (s_i qd)^2)
+ 1/2 sum_j a_j qd_j^2``, with ``J_i`` the Jacobian of link i's centre of mass and ``s_i`` the
row of the revolute joints on its path from the world (each joint's ``sense``, 0 elsewhere). Lagrange's equations
then give

- ``M = d2T/dqd2 = sum_i m_i J_i^T J_i + I_i s_i^T s_i + diag(armature)``,
- ``C qd = sum_i m_i J_i^T (dJ_i/dt) qd`` (the velocity-product acceleration of each centre of
  mass, pulled back to the joints; the planar rotation terms have none),
- ``T(q) = dV/dq = sum_i m_i g J_i^T e_z``,

and the joints' dampers ``D qd``, springs ``K (q - q_ref)``, the limits' penalty forces ``tau_limits``
(:class:`lagrange.PenaltyLimits`) and the contact forces ``f_s`` at the contact spots ``s``
(:class:`lagrange.PenaltyContact`) are generalized forces beside ``B u``.

This module checks the arguments and the parameters and picks one of two derivations by the chain's size, here and
nowhere else:

- chains of fewer than ``RECURSIVE_MIN`` links: :mod:`lagrange.planar.unrolled`, where ``J_i`` and ``(dJ_i/dt) qd`` are
  differentiated at trace time from the forward kinematics written as sums of unit vectors, simplified at trace time,
  so the compiled program contains only the terms the chain has, and ``M qdd = rhs`` is solved unrolled over scalars;
- chains of ``RECURSIVE_MIN`` or more links: the recursive algorithms of :mod:`lagrange.planar.recursive`
  (ABA, RNEA, CRBA as scans over the links), whose work grows like n rather than n^3.

The tests check both against the literal derivation (Hessians of the Lagrangian,
``oracles/euler_lagrange.py``) and hand-written closed forms.

Shapes: ``n`` links, ``m`` actuated joints. Every function is pure, takes ``q``/``qd``/``u``/``qdd``
with any leading batch dimensions ``*batch`` (broadcast against each other), and is safe under
``jit``, ``vmap`` and ``grad``. Units: SI, with a joint's coordinate in rad (revolute) or m
(prismatic) and its generalized force in N m or N.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from lagrange import rbda as spatial
from lagrange.planar import recursive, unrolled
from lagrange.forces import actuation_matrix
from lagrange.chain import Chain
from lagrange.model.checks import check_parameters
from lagrange.model.tree import Tree

__all__ = ["RECURSIVE_MIN", "SINGULAR", "actuation_matrix", "bias_forces", "energy", "forward_dynamics",
           "forward_dynamics_and_pivots", "gravity_forces", "inverse_dynamics", "mass_matrix"]


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


def _prepared(chain: Chain, *, at_run_time: bool = True) -> Chain:
    """``chain`` with its parameters checked (:func:`lagrange.model.checks.check_parameters`: concrete ones now, traced
    ones when run unless ``at_run_time=False``) and folded (:func:`_folded`)."""
    return _folded(check_parameters(chain, at_run_time=at_run_time))


def _check(chain: Chain | Tree, name: str, x, size: int | None = None):
    if size is None:  # q has nq entries, qd and qdd nv, u m
        size = {"q": getattr(chain, "nq", chain.n), "u": chain.m}.get(name, chain.n)
    shape = jnp.shape(x)
    if len(shape) == 0 or shape[-1] != size:
        what = " (the chain has no actuated joint: pass u=None)" if name == "u" and size == 0 else ""
        raise ValueError(f"{name} must have shape (..., {size}) for this chain{what}, got {shape}")


RECURSIVE_MIN = 4
"""Chains of at least this many links use the recursive algorithms of :mod:`lagrange.planar.recursive`
(ABA for ``forward_dynamics``, CRBA for ``mass_matrix``, RNEA for the forces,
``inverse_dynamics`` and ``energy``): O(n) work (O(n^2) for M) and a compiled program whose size
does not depend on n. Shorter chains keep the unrolled relative-angle derivation above, which needs
the sine and cosine of every pair of link angles (O(n^2) transcendentals) and whose program grows
like n^3. Measured on n-link pendulums, compiled arithmetic ops of the relative-angle derivation (in
parentheses: an alternative unrolled derivation by sparse second-order jets of the forward kinematics,
O(n) transcendentals): n=2 38 (68), n=3 131 (160), n=4 458 (494), n=5 1110 (950), n=6 2390 (1648).

Measured on n-link pendulums (every joint actuated), semi-implicit Euler rollouts of 20 steps,
float64, one process on a 2-core machine, microseconds per env-step, unrolled / recursive
(``jax.vmap`` over the batch):

- n = 2: batch 1 forward 0.39 / 1.2, gradient 0.46 / 6.8; batch 1024 forward 0.035 / 0.058, gradient 0.16 / 0.27.
- n = 3: batch 1 forward 0.42 / 1.3, gradient 1.3 / 8.8; batch 1024 forward 0.13 / 0.08, gradient 0.68 / 0.41.
- n = 4: batch 1 forward 1.3 / 3.9, gradient 4.0 / 17; batch 1024 forward 0.96 / 0.10, gradient 2.1 / 0.51.

Each link costs the recursive path three loop iterations per evaluation (kinematics, ABA's two passes), ~0.1-0.5 us
each at batch 1, while at batch 1024 its vectorised per-link steps win from n = 3 and by 9x at n = 4. The unrolled
path is kept where it is as fast or faster at both sizes (n <= 3, where it reaches the hand-written closed forms,
``benchmarks/derivation_overhead.py``); the recursive path from n = 4, where batched simulation, the case of the
library's training loops, gains most. Hence 4 (a vmapped function is traced once per example, so the choice cannot
depend on the batch size)."""


def _recursive(chain: Chain) -> bool:
    return not isinstance(chain, Tree) and chain.n >= RECURSIVE_MIN


def _derivation(chain: Chain | Tree):
    """The module that computes for ``chain``: :mod:`lagrange.rbda` for a 3-D tree, else by the chain's size the
    recursive algorithms or the unrolled derivation."""
    if isinstance(chain, Tree):
        return spatial
    return recursive if _recursive(chain) else unrolled


def _operands(chain: Chain | Tree, *xs):
    """A tree's arguments as JAX arrays (``None`` kept); a chain's as given (its derivations fold NumPy constants)."""
    if isinstance(chain, Tree):
        return tuple(None if x is None else jnp.asarray(x) for x in xs)
    return xs


SINGULAR = (
    "lagrange.forward_dynamics: the mass matrix is singular (a non-positive pivot in its factorisation) at this "
    "configuration: some motion of the joints moves no mass, inertia or armature here, e.g. a massless link "
    "carrying a point mass as the joints align. Give the links an inertia > 0 or the joints an armature > 0"
)
"""The error :func:`forward_dynamics` raises at a configuration where ``M`` is singular."""


def mass_matrix(chain: Chain, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n n"]:
    """The mass matrix ``M(q)``, symmetric positive semi-definite (definite for a regular chain).

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.

    Returns:
        ``M``, shape ``(*batch, n, n)`` [kg m^2, kg m or kg].
    """
    _check(chain, "q", q)
    chain = _prepared(chain)
    return _derivation(chain).mass_matrix(chain, *_operands(chain, q))


def bias_forces(
    chain: Chain, q: Float[ArrayLike, "*batch n"], qd: Float[ArrayLike, "*batch n"]
) -> Float[Array, "*batch n"]:
    """``C(q, qd) qd + T(q) + D qd + K (q - q_ref) - tau_limits - sum_s J_s^T f_s``: what the joints must supply at
    ``qdd = 0``.

    The velocity products, gravity, the joints' dampers and springs, minus the limits' penalty forces and the contact
    forces (each term only where the chain has it). For a model read by :func:`~lagrange.interop.mjcf.from_mjcf`
    without limits and contact it equals MuJoCo's ``qfrc_bias - qfrc_passive``.

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.

    Returns:
        Shape ``(*batch, n)`` [N m or N].
    """
    _check(chain, "q", q)
    _check(chain, "qd", qd)
    chain = _prepared(chain)
    return _derivation(chain).bias_forces(chain, *_operands(chain, q, qd))


def gravity_forces(chain: Chain, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n"]:
    """``T(q) = dV/dq``: the generalized gravity forces (no springs, limits or contact).

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.

    Returns:
        Shape ``(*batch, n)`` [N m or N].
    """
    _check(chain, "q", q)
    chain = _prepared(chain)
    return _derivation(chain).gravity_forces(chain, *_operands(chain, q))


def forward_dynamics(
    chain: Chain,
    q: Float[ArrayLike, "*batch n"],
    qd: Float[ArrayLike, "*batch n"],
    u: Float[ArrayLike, "*batch m"] | None = None,
    *,
    implicit_damping_dt: float | Float[ArrayLike, ""] | None = None,
    check: bool = True,
) -> Float[Array, "*batch n"]:
    """Joint accelerations ``qdd = M^-1 (B u - bias_forces(chain, q, qd))``.

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.
        u: controls, shape ``(*batch, m)`` (generalized force ``gear * u`` on each actuated joint, ``u``
            first clamped into the joint's ``control_range`` where it has one); ``None`` (no control) or
            omitted for an unactuated chain.
        implicit_damping_dt: ``h`` [s] to solve with ``M + h diag(damping)`` instead of ``M``, the velocity
            update of :class:`lagrange.SemiImplicitEuler` (damping treated implicitly); ``None`` for ``M``.
        check: raise where ``M`` is singular at ``q``, or where a traced parameter breaks its rule
            (:func:`lagrange.model.checks.check_parameters`); ``False`` skips both run-time checks (a NaN or Inf then
            comes out instead, as inside :func:`lagrange.simulate`, which checks the parameters once and the final
            state). Concrete parameters are checked while tracing either way.

    Returns:
        ``qdd``, shape ``(*batch, n)`` [rad/s^2 or m/s^2].

    Raises:
        ValueError: (while tracing) for a concrete parameter that breaks its rule (a negative mass set by
            ``eqx.tree_at``, ...), naming the field and the link.
        equinox.EquinoxRuntimeError: (when run, with ``check=True``) if ``M`` is singular at ``q`` (a pivot of its
            factorisation is not positive), with :data:`SINGULAR` as the message, or if a traced parameter breaks its
            rule (naming the field and the link).
    """
    if not check:
        return _forward(chain, q, qd, u, implicit_damping_dt, pivots=False, at_run_time=False)
    qdd, singular = _forward(chain, q, qd, u, implicit_damping_dt, pivots=True, at_run_time=True)
    return eqx.error_if(qdd, singular, SINGULAR)


def forward_dynamics_and_pivots(
    chain: Chain,
    q: Float[ArrayLike, "*batch n"],
    qd: Float[ArrayLike, "*batch n"],
    u: Float[ArrayLike, "*batch m"] | None = None,
    *,
    implicit_damping_dt: float | Float[ArrayLike, ""] | None = None,
) -> tuple[Float[Array, "*batch n"], Bool[Array, " *batch"]]:
    """:func:`forward_dynamics` without its check, and where it would raise.

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.
        u: controls, shape ``(*batch, m)``, or ``None`` (as for :func:`forward_dynamics`).
        implicit_damping_dt: as for :func:`forward_dynamics` [s].

    Returns:
        ``(qdd, singular)``: ``qdd`` of shape ``(*batch, n)`` and ``singular`` of shape ``(*batch,)``, true where a
        pivot of the factorisation of ``M`` (ABA's articulated inertias ``D_i``; the LDL^T pivots, or the
        determinant for n <= 3) is not positive or not finite.
    """
    return _forward(chain, q, qd, u, implicit_damping_dt, pivots=True, at_run_time=True)


def _forward(chain: Chain, q, qd, u, implicit_damping_dt, *, pivots: bool, at_run_time: bool):
    _check(chain, "q", q)
    _check(chain, "qd", qd)
    if u is not None:
        _check(chain, "u", u)
    chain = _prepared(chain, at_run_time=at_run_time)
    return _derivation(chain).forward_dynamics(chain, *_operands(chain, q, qd, u),
                                               implicit_damping_dt=implicit_damping_dt, pivots=pivots)


def inverse_dynamics(
    chain: Chain,
    q: Float[ArrayLike, "*batch n"],
    qd: Float[ArrayLike, "*batch n"],
    qdd: Float[ArrayLike, "*batch n"],
) -> Float[Array, "*batch n"]:
    """The generalized forces ``M qdd + bias_forces(chain, q, qd)`` that produce the accelerations ``qdd``.

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.
        qdd: joint accelerations [rad/s^2 or m/s^2], shape ``(*batch, n)``.

    Returns:
        Shape ``(*batch, n)`` [N m or N]; equal to ``B u`` when ``qdd = forward_dynamics(chain, q, qd, u)``.
    """
    _check(chain, "qdd", qdd)
    chain = check_parameters(chain)
    if isinstance(chain, Tree) or _recursive(chain):
        _check(chain, "q", q)
        _check(chain, "qd", qd)
        if isinstance(chain, Tree):
            return spatial.inverse_dynamics(_folded(chain), jnp.asarray(q), jnp.asarray(qd), jnp.asarray(qdd))
        return recursive.inverse_dynamics(chain, q, qd, qdd)
    return jnp.einsum("...ij,...j->...i", mass_matrix(chain, q), qdd) + bias_forces(chain, q, qd)


def energy(
    chain: Chain, q: Float[ArrayLike, "*batch n"], qd: Float[ArrayLike, "*batch n"]
) -> tuple[Float[Array, " *batch"], Float[Array, " *batch"]]:
    """The kinetic and potential energy, the potential with every spring's.

    Args:
        chain: the :class:`~lagrange.chain.Chain`.
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.

    Returns:
        ``(kinetic, potential)`` [J], each of shape ``(*batch,)``. The potential is gravity's (zero with the chain's
        origin at z = 0), plus the joint springs' ``1/2 K (q - q_ref)^2``, the limits' ``1/2 ke (q - bound)^2`` outside
        the ranges and the contact's ``1/2 ke d^2`` of the points below the ground.
    """
    _check(chain, "q", q)
    _check(chain, "qd", qd)
    chain = check_parameters(chain)
    if isinstance(chain, Tree):
        chain = _folded(chain)
    return _derivation(chain).energy(chain, *_operands(chain, q, qd))
