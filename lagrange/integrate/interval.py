"""One control interval of a tree: the solvers' steps, fixed or adaptive, on the coordinates' manifold.

Fixed-step explicit Runge-Kutta solvers run from their diffrax Butcher tableau, unrolled, zero coefficients and unused
stages dropped while tracing; a tree's coordinates move through its joints (quaternions by the exponential map: the
stage and final coordinates from the step's start by the weighted velocity sum, MuJoCo's ``mj_RungeKutta``), a planar
tree's as a vector. Semi-implicit Euler is MuJoCo's, Brax's and DFlex's step; symplectic Euler in momenta
(MomentumEuler) runs where the coordinates are a vector. Adaptive steps and diffrax adjoints run each interval through
``diffrax.diffeqsolve``. :func:`lagrange.simulate` and :func:`lagrange.step` check the arguments, prepare the backend
(:func:`lagrange.dynamics.backend`) and call :func:`interval_map`, which calls the backend's methods only.
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from lagrange.backend import AbstractBackend
from lagrange.integrate.solvers import SOLVERS, Euler, MomentumEuler, SemiImplicitEuler, is_adaptive_capable

__all__ = ["check_solver", "interval_map"]


def check_solver(solver: object) -> None:
    """Raise a ``TypeError`` naming the allowed solvers unless ``solver`` is an instance of one of them."""
    if isinstance(solver, (SemiImplicitEuler, MomentumEuler, Euler, diffrax.AbstractERK)):
        return
    if isinstance(solver, type):
        raise TypeError(
            f"solver must be a solver instance, got the class {solver.__name__}; write {solver.__name__}()"
        )
    names = ", ".join(f"lagrange.{c.__name__}()" for c in SOLVERS)
    raise TypeError(
        f"solver must be one of {names} or another explicit diffrax Runge-Kutta solver, got {solver!r}"
    )


def _spd_solver(A):
    """``b -> A^-1 b`` for a (batch of) symmetric positive-definite array ``A`` of shape ``(*batch, n, n)``, factored
    once by Cholesky (for solving with the same matrix several times, as :class:`lagrange.MomentumEuler` does).

    Args:
        A: shape ``(*batch, n, n)``.

    Returns:
        A function of ``b`` (shape ``(*batch, n)``) returning ``A^-1 b`` (shape ``(*batch, n)``).
    """
    L = jnp.linalg.cholesky(A)

    def solve(b):
        y = jax.lax.linalg.triangular_solve(L, b[..., None], left_side=True, lower=True)
        return jax.lax.linalg.triangular_solve(L, y, left_side=True, lower=True, transpose_a=True)[..., 0]

    return solve


def _needed_stages(tableau) -> list[bool]:
    b = np.asarray(tableau.b_sol)
    s = len(b)
    need = [bool(b[i] != 0) for i in range(s)]
    for i in reversed(range(1, s)):
        if need[i]:
            for j, a in enumerate(np.asarray(tableau.a_lower[i - 1])):
                if a != 0:
                    need[j] = True
    return need


def _axpy(y, h, coeffs, ks):
    """y + h * sum_j coeffs[j] * ks[j], skipping zero coefficients (tuples of arrays)."""
    out = list(y)
    for c, k in zip(coeffs, ks):
        c = float(c)
        if c == 0.0:
            continue
        w = h * c
        out = [o + w * kk for o, kk in zip(out, k)]
    return tuple(out)


def _erk_step(b: AbstractBackend, f, tableau, h, y):
    if not b.euclidean:
        return _rkmk_step(b, f, tableau, h, y)
    need = _needed_stages(tableau)
    ks = [None] * len(need)
    for i, needed in enumerate(need):
        if not needed:
            continue
        yi = y if i == 0 else _axpy(y, h, tableau.a_lower[i - 1], ks[:i])
        ks[i] = f(yi)
    return _axpy(y, h, tableau.b_sol, ks)


def _weighted(coeffs, xs):
    """``sum_j c_j x_j`` over the non-zero ``c_j`` (``None`` when there is none)."""
    terms = [float(c) * x for c, x in zip(coeffs, xs) if float(c) != 0.0]
    return sum(terms[1:], terms[0]) if terms else None


def _rkmk_step(b: AbstractBackend, f, tableau, h, y):
    """An explicit Runge-Kutta step on a tree's coordinates (Runge-Kutta-Munthe-Kaas): every stage at
    ``q0 exp(h d_i)`` with ``d_i = sum_j a_ij K_j``, ``K_j`` stage ``j``'s velocity as the rate of its tangent
    increment (:func:`lagrange.rbda.dexpinv`; the velocity itself for hinges, slides and positions), the step to
    ``q0 exp(h sum_j b_j K_j)``; velocities as in a vector space. It keeps the method's order on the quaternions
    (MuJoCo's ``mj_RungeKutta``, the same without ``dexpinv``, is second order in the rotations: measured in
    ``tests/lagrange/rbda/test_rbda.py``)."""
    q0, qd0 = y
    need = _needed_stages(tableau)
    K, acc = [None] * len(need), [None] * len(need)
    for i, needed in enumerate(need):
        if not needed:
            continue
        if i == 0:
            K[0], acc[0] = f(y)
            continue
        a = tableau.a_lower[i - 1]
        d, dv = _weighted(a, K[:i]), _weighted(a, acc[:i])
        qi = q0 if d is None else b.move(q0, d, h)
        v, acc[i] = f((qi, qd0 if dv is None else qd0 + h * dv))
        K[i] = v if d is None else b.dexpinv(h * d, v)
    d, dv = _weighted(tableau.b_sol, K), _weighted(tableau.b_sol, acc)
    return b.move(q0, d, h), qd0 + h * dv


def _momentum_euler_step(b: AbstractBackend, iterations: int, h, q, qd, u):
    """One step of :class:`lagrange.MomentumEuler` (see its docstring for the scheme)."""
    M = b.mass_matrix(q)
    p = jnp.einsum("...ij,...j->...i", M, qd)
    force = -b.gravity_forces(q)
    springs = b.spring_forces(q)  # the joint springs, a potential force like gravity
    if springs is not None:
        force = force - springs
    actuation = None if u is None else b.actuation(u, q, qd)
    if actuation is not None:
        force = force + actuation
    A = M if b.damping is None else M + h * jnp.diag(b.damping)
    solve = _spd_solver(A)
    # dT/dq at fixed v; the sum over a batch leaves each state's gradient its own
    dkin_dq = jax.grad(lambda q_, v: jnp.sum(b.energy(q_, v)[0]))
    v = qd
    for _ in range(iterations):
        v = solve(p + h * (force + dkin_dq(q, v)))
    q1 = q + h * v
    p1 = jnp.einsum("...ij,...j->...i", M, v)
    return q1, _spd_solver(b.mass_matrix(q1))(p1)


def _fixed_substep(b: AbstractBackend, solver, h, q, qd, u):
    if isinstance(solver, MomentumEuler):
        return _momentum_euler_step(b, solver.iterations, h, q, qd, u)
    if isinstance(solver, SemiImplicitEuler):
        qdd = b.forward_dynamics(q, qd, u, h if solver.implicit_damping else None)
        qd1 = qd + h * qdd
        return b.move(q, qd1, h), qd1

    def f(y):
        return (y[1], b.forward_dynamics(y[0], y[1], u))

    if isinstance(solver, diffrax.Euler):
        qdd = f((q, qd))[1]
        return b.move(q, qd, h), qd + h * qdd
    return _erk_step(b, f, solver.tableau, h, (q, qd))


def _held_mass_matrix_interval(b: AbstractBackend, solver: SemiImplicitEuler, h, substeps: int):
    """Semi-implicit Euler with ``M`` (``+ h diag(damping)`` with implicit damping) formed and Cholesky-factored at the
    interval's start (and every ``solver.mass_matrix_every`` substeps) and used by the substeps until the next; the
    forces ``tau - bias`` of every substep's own state. (An LDL^T unrolled over the entries ran as fast and compiled 4x
    longer for the cheetah's 9 dof.)"""
    every = substeps if solver.mass_matrix_every is None else solver.mass_matrix_every
    if substeps % every:
        raise ValueError(f"SemiImplicitEuler.mass_matrix_every={every} must divide substeps={substeps}")

    def block(q, qd, u, length):
        M = b.mass_matrix(q)
        if solver.implicit_damping and b.damping is not None:
            M = M + h * jnp.diag(b.damping)
        solve = _spd_solver(M)
        Bu = None if u is None or b.state_dependent_actuation else b.actuation(u)
        Bu = 0.0 if Bu is None else Bu

        def body(carry, _):
            q, qd = carry
            if u is not None and b.state_dependent_actuation:
                qdd = solve(b.actuated_forces(q, qd, u))
            else:
                qdd = solve(Bu - b.bias_forces(q, qd))
            qd1 = qd + h * qdd
            return (b.move(q, qd1, h), qd1), None

        return jax.lax.scan(_remat(solver, body), (q, qd), None, length=length)[0]

    if every == substeps:
        return lambda q, qd, u: block(q, qd, u, substeps)

    def interval(q, qd, u):
        return jax.lax.scan(lambda carry, _: (block(*carry, u, every), None), (q, qd), None,
                            length=substeps // every)[0]

    return interval


def _remat(solver, body):
    """``body`` recomputed in the backward pass when the solver asks for it (``checkpoint_substeps``)."""
    return jax.checkpoint(body) if isinstance(solver, SemiImplicitEuler) and solver.checkpoint_substeps else body


def interval_map(b: AbstractBackend, solver, dt, substeps, adjoint, rtol, atol, max_steps):
    """The map ``(q, qd, u) -> (q, qd)`` over one control interval of ``dt`` seconds of the prepared tree ``b`` (the
    other arguments as :func:`lagrange.simulate` takes them, checked there)."""
    adaptive = rtol is not None or atol is not None
    if adaptive:
        if rtol is None or atol is None:
            raise ValueError("adaptive stepping needs both rtol and atol (positive floats), got only one")
        if not (rtol > 0 and atol > 0):
            raise ValueError(f"rtol and atol must be > 0, got rtol={rtol}, atol={atol}")
        if not is_adaptive_capable(solver):
            raise ValueError(
                f"{type(solver).__name__} has no embedded error estimate, so rtol/atol cannot be used; "
                "use Tsit5(), Dopri5() or Dopri8() for adaptive steps, or drop rtol/atol"
            )
    if not b.euclidean and isinstance(solver, MomentumEuler):
        raise NotImplementedError("MomentumEuler runs on planar trees only (its canonical momenta assume coordinates "
                                  "that the velocities integrate, nq = nv); use SemiImplicitEuler, RK4 or an adaptive "
                                  "solver for a tree with balls or free joints or hinges about several axes")
    if isinstance(solver, (SemiImplicitEuler, MomentumEuler)) and adjoint is not None:
        raise ValueError(f"{type(solver).__name__} runs outside diffeqsolve; pass adjoint=None")
    h = dt / substeps

    if isinstance(solver, SemiImplicitEuler) and solver.hold_mass_matrix:
        return _held_mass_matrix_interval(b, solver, h, substeps)

    if not adaptive and adjoint is None:

        def interval(q, qd, u):
            if substeps == 1:
                return _fixed_substep(b, solver, h, q, qd, u)

            def body(carry, _):
                return _fixed_substep(b, solver, h, *carry, u), None

            return jax.lax.scan(_remat(solver, body), (q, qd), None, length=substeps)[0]

        return interval

    # the coordinates in R^nq, dq/dt from the joints (a quaternion's 1/2 q (0, w)); the quaternions renormalised
    term = diffrax.ODETerm(lambda t, y, u: (b.rate(y[0], y[1]), b.forward_dynamics(y[0], y[1], u)))
    controller = (
        diffrax.PIDController(rtol=rtol, atol=atol) if adaptive else diffrax.ConstantStepSize()
    )
    adj = adjoint if adjoint is not None else diffrax.RecursiveCheckpointAdjoint()

    def interval(q, qd, u):
        t = jnp.result_type(q, qd)  # times in the state's dtype: float64 ones would promote a float32 state
        sol = diffrax.diffeqsolve(
            term,
            solver,
            jnp.asarray(0.0, t),
            jnp.asarray(dt, t),
            jnp.asarray(h, t),
            (q, qd),
            args=u,
            stepsize_controller=controller,
            adjoint=adj,
            saveat=diffrax.SaveAt(t1=True),
            max_steps=max_steps if adaptive else substeps,
        )
        q1 = sol.ys[0][0]
        return b.normalize(q1), sol.ys[1][0]

    return interval
