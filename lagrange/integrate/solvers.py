"""Integrators: diffrax solvers, plus the semi-implicit Euler that MuJoCo and Brax use.

- :class:`RK4` is the classic fourth-order Runge-Kutta method written as a diffrax Butcher
  tableau (a :class:`diffrax.AbstractERK`), so it runs inside ``diffrax.diffeqsolve`` too.
- ``Euler``, ``Tsit5``, ``Dopri5`` and ``Dopri8`` are diffrax's own solvers, re-exported.
- :class:`MomentumEuler` is symplectic Euler in the canonical momenta: bounded energy error
  on any chain (implicit; a few fixed-point sweeps per step).
- :class:`SemiImplicitEuler` is semi-implicit Euler for second-order systems,
  ``qd' = qd + h qdd(q, qd, u)``, ``q' = q + h qd'``, with joint damping treated implicitly
  (``(M + h diag(damping)) qdd = ...``) exactly as MuJoCo's and Brax's ``Euler`` integrators.

Fixed-step explicit Runge-Kutta methods are executed by :mod:`lagrange.integrate` straight
from their tableau, unrolled, with zero coefficients and unused stages dropped at trace time.
"""

from __future__ import annotations

import warnings
from typing import ClassVar

import diffrax
import equinox as eqx
import numpy as np
from diffrax import Dopri5, Dopri8, Euler, Tsit5

_rk4_tableau = diffrax.ButcherTableau(
    c=np.array([0.5, 0.5, 1.0]),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    b_error=np.zeros(4),
    a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
)


class RK4(diffrax.AbstractERK):
    """Classic fourth-order Runge-Kutta (no embedded error estimate: fixed steps only)."""

    tableau: ClassVar[diffrax.ButcherTableau] = _rk4_tableau
    interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation.from_k

    def order(self, terms):
        return 4


class SemiImplicitEuler(eqx.Module):
    """Semi-implicit Euler for ``M qdd + ... = B u``; first order, fixed steps only.

    It updates velocities, not momenta, so it is symplectic (bounded energy error) only where
    ``M`` is constant, e.g. a single pendulum or a cart; on a double pendulum its energy error
    drifts (measured: -0.48 of the energy above rest over 1e5 steps of 1e-3 s, see
    ``tests/lagrange/test_stability.py``). It is here because it is exactly MuJoCo's, Brax's and DFlex's step.

    ``qd' = qd + h qdd``, ``q' = q + h qd'``. By default joint damping enters the velocity update
    implicitly: ``(M + h diag(damping)) qdd = B u - C qd - T - damping qd``, MuJoCo's
    ``integrator="Euler"`` and Brax's generalized pipeline, step for step.

    Attributes:
        implicit_damping (bool): treat joint damping implicitly (MuJoCo, Brax); ``False``: explicitly with every
            other force (DFlex); static.
        hold_mass_matrix (bool): form and factor ``M`` once per control interval, at its start, and use it for
            every substep of the interval (DFlex's ``MM_caching_frequency`` equal to its substeps, as the SHAC
            configs run it); the forces are evaluated every substep. ``False`` (the default): ``M`` of every
            substep's own state; static.
        mass_matrix_every (int | None): with ``hold_mass_matrix``, form ``M`` anew every this many substeps (DFlex's
            ``MM_caching_frequency``: the SNU humanoid's 8 of 48), which must divide ``substeps``; ``None`` (the
            default): once per interval; static.
        checkpoint_substeps (bool): recompute each substep's intermediates in the backward pass (``jax.checkpoint``)
            instead of storing them: the same values, gradients equal to round-off, memory of one state per
            substep. Measured on a CPU (SHAC's 32-step window of DFlex's humanoid, 48 substeps, 64 envs, float32):
            gradients 1.6x faster; the ant's (16 substeps) 1.15x. ``False`` (the default): store them; static.
    """

    implicit_damping: bool = eqx.field(static=True, default=True)
    hold_mass_matrix: bool = eqx.field(static=True, default=False)
    checkpoint_substeps: bool = eqx.field(static=True, default=False)
    mass_matrix_every: int | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        for name in ("implicit_damping", "hold_mass_matrix", "checkpoint_substeps"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"SemiImplicitEuler.{name} must be True or False, got {getattr(self, name)!r}")
        every = self.mass_matrix_every
        if every is not None and (isinstance(every, bool) or not isinstance(every, int) or every < 1):
            raise ValueError(f"SemiImplicitEuler.mass_matrix_every must be None or an integer >= 1, got {every!r}")
        if every is not None and not self.hold_mass_matrix:
            raise ValueError("SemiImplicitEuler.mass_matrix_every needs hold_mass_matrix=True (without it M is formed "
                             "at every substep)")

    def order(self, terms=None):
        return 1


class MomentumEuler(eqx.Module):
    """Symplectic Euler in canonical momenta ``p = M(q) qd``; first order, fixed steps only.

    Formerly ``SymplecticEuler``: textbooks give that name to :class:`SemiImplicitEuler`'s velocity form too, so the
    name now says what differs, the momenta. ``lagrange.SymplecticEuler`` still gives this class, with a
    ``DeprecationWarning``.

    The Hamiltonian ``H = 1/2 p^T M(q)^-1 p + V(q) - (B u)^T q`` (``u`` held over the step) is
    non-separable, so the scheme is implicit in the new momentum::

        (M(q) + h D) v = M(q) qd + h (B u - T(q) + dT/dq(q, v)),    q' = q + h v,
        qd' = M(q')^-1 M(q) v

    with ``T(q, v) = 1/2 v^T M(q) v`` the kinetic energy and ``D`` the joint damping (implicit, as
    in :class:`SemiImplicitEuler`). The map ``(q, p) -> (q', p')`` is symplectic Euler, so without
    damping its energy error stays bounded (O(h)) on any chain, where the velocity-form
    :class:`SemiImplicitEuler` drifts once ``M`` depends on ``q``. With a constant ``M``
    (``dT/dq = 0``) the two are the same step.

    ``v`` is found by a fixed number of fixed-point sweeps from ``v = qd``; each shrinks the error
    by a factor of about ``h |qd|`` (rad). Measured on the acrobot at h = 1e-3 with speeds up to
    ~30 rad/s (``h |qd| ~ 0.03``): the new velocity is off by 1e-3 after 2 sweeps, 9e-7 after 4,
    9e-10 after 6 and 9e-13 rad/s after the default 8; raise ``iterations`` for faster motion
    or larger steps (the sweeps diverge, and ``simulate(check=True)`` reports the non-finite
    state, once ``h |qd|`` nears 1). Without convergence the step is not exactly symplectic, but
    its error per step is then the residual, far below the O(h) energy oscillation. Each sweep
    costs one gradient of the kinetic energy and one solve with the once-factored ``M + h D``:
    several times a :class:`SemiImplicitEuler` step.
    """

    iterations: int = eqx.field(static=True, default=8)

    def __check_init__(self):
        if isinstance(self.iterations, bool) or not isinstance(self.iterations, int) or self.iterations < 1:
            raise ValueError(f"MomentumEuler: iterations must be an int >= 1, got {self.iterations!r}")

    def order(self, terms=None):
        return 1


SOLVERS = (RK4, Euler, SemiImplicitEuler, MomentumEuler, Tsit5, Dopri5, Dopri8)
"""The solvers this library has been checked with (any explicit diffrax ERK also works)."""


def order(solver: diffrax.AbstractSolver | SemiImplicitEuler | MomentumEuler) -> int:
    """Classical order of accuracy of a solver."""
    return int(solver.order(None))


def is_adaptive_capable(solver: diffrax.AbstractSolver | SemiImplicitEuler | MomentumEuler) -> bool:
    """Whether the solver has an embedded error estimate (so rtol/atol can be used)."""
    if not isinstance(solver, diffrax.AbstractERK):
        return False
    return bool(np.any(np.asarray(solver.tableau.b_error) != 0))


RENAMED = {"SymplecticEuler": "MomentumEuler"}
"""Old public names of this module's solvers and their new names; the old ones still resolve, with a warning."""


def renamed(name: str, module: str = "lagrange") -> type:
    """The solver class an old name of :data:`RENAMED` stands for, with a ``DeprecationWarning`` attributed to the
    code that looked the old name up (``lagrange.NAME`` or ``lagrange.integrate.solvers.NAME``).

    Raises:
        AttributeError: for a name that is not an old name.
    """
    if name not in RENAMED:
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    warnings.warn(f"lagrange.{name} is renamed lagrange.{RENAMED[name]} (the same solver); the old name will be "
                  f"removed", DeprecationWarning, stacklevel=3)  # renamed <- the module's __getattr__ <- the caller
    return globals()[RENAMED[name]]


def __getattr__(name: str) -> type:
    return renamed(name, __name__)


__all__ = ["RK4", "Euler", "SemiImplicitEuler", "MomentumEuler", "Tsit5", "Dopri5", "Dopri8", "SOLVERS"]
