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

This module checks the arguments and the parameters once, at the public entry, and picks the backend
(:func:`backend`), here and nowhere else, by the tree's structure:

- a planar tree (:attr:`lagrange.Tree.planar`: hinges about one axis, slides across it), lowered to the planar
  backend's chain while tracing (:func:`lagrange.planar.lower.lower`): of fewer than ``RECURSIVE_MIN`` links the
  unrolled derivation (:class:`~lagrange.planar.unrolled.Unrolled`), where ``J_i`` and ``(dJ_i/dt) qd`` are
  differentiated at trace time from the forward kinematics written as sums of unit vectors, simplified at trace time,
  so the compiled program contains only the terms the chain has, and ``M qdd = rhs`` is solved unrolled over scalars;
  of ``RECURSIVE_MIN`` or more the recursive algorithms (:class:`~lagrange.planar.recursive.Recursive`: ABA, RNEA, CRBA
  as scans over the links), whose work grows like n rather than n^3;
- any other tree (balls, free joints, hinges about several axes): the general rigid-body algorithms
  (:class:`~lagrange.rbda.backend.General`), which take a planar tree too (``general=True``).

The tests check the planar ones against the literal derivation (Hessians of the Lagrangian,
``oracles/euler_lagrange.py``) and hand-written closed forms, and every planar model both ways.

Shapes: ``nq`` coordinates, ``nv`` velocities (``n`` of each for a planar chain), ``m`` controls. Every function is
pure, takes ``q``/``qd``/``u``/``qdd`` with any leading batch dimensions ``*batch`` (broadcast against each other), and
is safe under ``jit``, ``vmap`` and ``grad``. Units: SI, with a joint's coordinate in rad (revolute) or m (prismatic)
and its generalized force in N m or N.
"""

from __future__ import annotations

import collections

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from lagrange.backend import AbstractBackend
from lagrange.forces import actuation_matrix
from lagrange.model.checks import check_parameters, check_shapes
from lagrange.model.tree import Tree, check_tree
from lagrange.planar.recursive import Recursive
from lagrange.planar.lower import lower
from lagrange.planar.unrolled import Unrolled
from lagrange.rbda.backend import General

__all__ = ["RECURSIVE_MIN", "SINGULAR", "actuation_matrix", "backend", "bias_forces", "energy", "forward_dynamics",
           "forward_dynamics_and_pivots", "gravity_forces", "inverse_dynamics", "mass_matrix", "prepare"]


def _as_constant(x):
    if isinstance(x, jax.Array) and not isinstance(x, jax.core.Tracer) and x.is_fully_addressable:
        return np.asarray(x)
    return x


def _folded(tree: Tree) -> Tree:
    """``tree`` with its concrete parameters as NumPy arrays, so that their products with each other are computed
    while tracing and reach XLA as literals. A tree closed over by a jitted function has concrete parameters, but
    XLA receives them as run-time operands of the time-stepping loop: it does not fold them, and on the CPU they can
    cost the fused step its vectorization (``python -m research.xla_vectorization``: the cartpole's
    closed form 1.7-1.9x slower with its constants as arrays). Parameters being differentiated or vmapped are
    tracers and stay as they are."""
    return jax.tree_util.tree_map(_as_constant, tree)


RECURSIVE_MIN = 4
"""Planar trees of at least this many links use the recursive algorithms of :mod:`lagrange.planar.recursive`
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


def backend(tree: Tree, *, check: bool = True, general: bool = False, name: str = "the model") -> AbstractBackend:
    """The tree prepared for the backend that derives its equations: the one place that chooses, by the tree's
    structure (the module docstring).

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`lagrange.chain.Chain` is one).
        check: also check its traced parameters when run (:func:`lagrange.model.checks.check_parameters`; concrete
            ones are checked now either way).
        general: the general rigid-body algorithms even for a planar tree (a cross-check of the planar backend).
        name: what the errors call ``tree``.

    Returns:
        The :class:`~lagrange.backend.AbstractBackend`, its concrete parameters folded to NumPy arrays.

    Raises:
        TypeError: for a model that is not a :class:`lagrange.Tree`, naming ``name``.
        ValueError: for a concrete parameter that breaks its rule.
    """
    key = _key(tree, check, general)
    if key is not None and key in _PREPARED:  # a concrete tree prepared before: checked and lowered already
        _PREPARED.move_to_end(key)
        return _PREPARED[key]
    check_tree(tree, name)
    tree = _folded(check_parameters(tree, at_run_time=check))
    chain = None if general or not tree.planar else lower(tree)
    if chain is None:
        out = General(tree)
    else:
        out = Unrolled(chain) if chain.n < RECURSIVE_MIN else Recursive(chain)
    if key is not None:
        _PREPARED[key] = out
        if len(_PREPARED) > 256:
            _PREPARED.popitem(last=False)
    return out


_PREPARED: collections.OrderedDict = collections.OrderedDict()
"""The backends of the concrete trees prepared last, by :func:`_key`: a tree used again (an eager call in a loop, a
second trace) is not checked and lowered again."""


def _key(tree: Tree, check: bool, general: bool):
    """The tree's static structure and the bytes of its parameters, or ``None`` where one is traced (a tree being
    differentiated or vmapped is prepared afresh). The structure names the model's class, so anything but a tree finds
    no prepared backend and is refused by :func:`backend`'s check."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    if any(isinstance(x, jax.core.Tracer) or (isinstance(x, jax.Array) and not x.is_fully_addressable)
           for x in leaves):
        return None
    values = tuple((np.asarray(x).dtype.str, np.shape(x), np.asarray(x).tobytes()) for x in leaves)
    return treedef, values, check, general


def prepare(tree: Tree, *, check: bool = True, general: bool = False, **arrays) -> AbstractBackend:
    """:func:`backend` after checking the shapes of ``arrays`` against the tree (``q (..., nq)``, ``qd`` and ``qdd
    (..., nv)``, ``u (..., m)``; ``None`` skipped): what every public function does first.

    Raises:
        ValueError: naming the array whose last axis does not match.
    """
    check_tree(tree)
    check_shapes(tree, **arrays)
    return backend(tree, check=check, general=general)


SINGULAR = (
    "lagrange.forward_dynamics: the mass matrix is singular (a non-positive pivot in its factorisation) at this "
    "configuration: some motion of the joints moves no mass, inertia or armature here, e.g. a massless link "
    "carrying a point mass as the joints align. Give the links an inertia > 0 or the joints an armature > 0"
)
"""The error :func:`forward_dynamics` raises at a configuration where ``M`` is singular."""


def mass_matrix(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch nv nv"]:
    """The mass matrix ``M(q)``, symmetric positive semi-definite (definite for a regular tree).

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`~lagrange.chain.Chain` is one).
        q: coordinates [rad or m], shape ``(*batch, nq)``.

    Returns:
        ``M``, shape ``(*batch, nv, nv)`` [kg m^2, kg m or kg].
    """
    return prepare(tree, q=q).mass_matrix(q)


def bias_forces(
    tree: Tree, q: Float[ArrayLike, "*batch nq"], qd: Float[ArrayLike, "*batch nv"]
) -> Float[Array, "*batch nv"]:
    """``C(q, qd) qd + T(q) + D qd + K (q - q_ref) - tau_limits - sum_s J_s^T f_s``: what the joints must supply at
    ``qdd = 0``.

    The velocity products, gravity, the joints' dampers and springs, minus the limits' penalty forces and the contact
    forces (each term only where the tree has it). For a model read by :func:`~lagrange.interop.mjcf.from_mjcf`
    without limits and contact it equals MuJoCo's ``qfrc_bias - qfrc_passive``.

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.
        qd: velocities [rad/s or m/s], shape ``(*batch, nv)``.

    Returns:
        Shape ``(*batch, nv)`` [N m or N].
    """
    return prepare(tree, q=q, qd=qd).bias_forces(q, qd)


def gravity_forces(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch nv"]:
    """``T(q) = dV/dq``: the generalized gravity forces (no springs, limits or contact).

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.

    Returns:
        Shape ``(*batch, nv)`` [N m or N].
    """
    return prepare(tree, q=q).gravity_forces(q)


def forward_dynamics(
    tree: Tree,
    q: Float[ArrayLike, "*batch nq"],
    qd: Float[ArrayLike, "*batch nv"],
    u: Float[ArrayLike, "*batch m"] | None = None,
    *,
    implicit_damping_dt: float | Float[ArrayLike, ""] | None = None,
    check: bool = True,
) -> Float[Array, "*batch nv"]:
    """Accelerations ``qdd = M^-1 (B u - bias_forces(tree, q, qd))``.

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.
        qd: velocities [rad/s or m/s], shape ``(*batch, nv)``.
        u: controls, shape ``(*batch, m)`` (generalized force ``gear * u`` on each driven joint, ``u`` first clamped
            into the motor's ``control_range`` where it has one); ``None`` (no control) or omitted for a tree
            without motors.
        implicit_damping_dt: ``h`` [s] to solve with ``M + h diag(damping)`` instead of ``M``, the velocity
            update of :class:`lagrange.SemiImplicitEuler` (damping treated implicitly); ``None`` for ``M``.
        check: raise where ``M`` is singular at ``q``, or where a traced parameter breaks its rule
            (:func:`lagrange.model.checks.check_parameters`); ``False`` skips both run-time checks (a NaN or Inf then
            comes out instead, as inside :func:`lagrange.simulate`, which checks the parameters once and the final
            state). Concrete parameters are checked while tracing either way.

    Returns:
        ``qdd``, shape ``(*batch, nv)`` [rad/s^2 or m/s^2].

    Raises:
        ValueError: (while tracing) for a concrete parameter that breaks its rule (a negative mass set by
            ``eqx.tree_at``, ...), naming the field.
        equinox.EquinoxRuntimeError: (when run, with ``check=True``) if ``M`` is singular at ``q`` (a pivot of its
            factorisation is not positive), with :data:`SINGULAR` as the message, or if a traced parameter breaks its
            rule (naming the field).
    """
    b = prepare(tree, check=check, q=q, qd=qd, u=u)
    if not check:
        return b.forward_dynamics(q, qd, u, implicit_damping_dt)
    qdd, singular = b.forward_dynamics(q, qd, u, implicit_damping_dt, pivots=True)
    return eqx.error_if(qdd, singular, SINGULAR)


def forward_dynamics_and_pivots(
    tree: Tree,
    q: Float[ArrayLike, "*batch nq"],
    qd: Float[ArrayLike, "*batch nv"],
    u: Float[ArrayLike, "*batch m"] | None = None,
    *,
    implicit_damping_dt: float | Float[ArrayLike, ""] | None = None,
) -> tuple[Float[Array, "*batch nv"], Bool[Array, " *batch"]]:
    """:func:`forward_dynamics` without its check, and where it would raise.

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.
        qd: velocities [rad/s or m/s], shape ``(*batch, nv)``.
        u: controls, shape ``(*batch, m)``, or ``None`` (as for :func:`forward_dynamics`).
        implicit_damping_dt: as for :func:`forward_dynamics` [s].

    Returns:
        ``(qdd, singular)``: ``qdd`` of shape ``(*batch, nv)`` and ``singular`` of shape ``(*batch,)``, true where a
        pivot of the factorisation of ``M`` (ABA's articulated inertias ``D_i``; the LDL^T or Cholesky pivots, or the
        determinant for n <= 3) is not positive or not finite.
    """
    return prepare(tree, q=q, qd=qd, u=u).forward_dynamics(q, qd, u, implicit_damping_dt, pivots=True)


def inverse_dynamics(
    tree: Tree,
    q: Float[ArrayLike, "*batch nq"],
    qd: Float[ArrayLike, "*batch nv"],
    qdd: Float[ArrayLike, "*batch nv"],
) -> Float[Array, "*batch nv"]:
    """The generalized forces ``M qdd + bias_forces(tree, q, qd)`` that produce the accelerations ``qdd``.

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.
        qd: velocities [rad/s or m/s], shape ``(*batch, nv)``.
        qdd: accelerations [rad/s^2 or m/s^2], shape ``(*batch, nv)``.

    Returns:
        Shape ``(*batch, nv)`` [N m or N]; equal to ``B u`` when ``qdd = forward_dynamics(tree, q, qd, u)``.
    """
    return prepare(tree, q=q, qd=qd, qdd=qdd).inverse_dynamics(q, qd, qdd)


def energy(
    tree: Tree, q: Float[ArrayLike, "*batch nq"], qd: Float[ArrayLike, "*batch nv"]
) -> tuple[Float[Array, " *batch"], Float[Array, " *batch"]]:
    """The kinetic and potential energy, the potential with every spring's.

    Args:
        tree: the :class:`lagrange.Tree`.
        q: coordinates [rad or m], shape ``(*batch, nq)``.
        qd: velocities [rad/s or m/s], shape ``(*batch, nv)``.

    Returns:
        ``(kinetic, potential)`` [J], each of shape ``(*batch,)``. The potential is gravity's (zero with the bodies'
        centres of mass at the world's z = 0), plus the joint springs' ``1/2 K (q - q_ref)^2``, the limits'
        ``1/2 ke (q - bound)^2`` outside the ranges and the contact's ``1/2 ke d^2`` of the points below the ground.
    """
    return prepare(tree, q=q, qd=qd).energy(q, qd)
