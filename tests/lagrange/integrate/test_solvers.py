"""The solvers (lagrange/integrate/solvers.py): RK4's Butcher tableau against the classical order conditions and, run
through diffrax's own explicit Runge-Kutta step, against the classical RK4 formulas written by hand; the orders and
adaptivity each solver reports; the refusal of anything that is not a solver, naming the allowed ones; and
MomentumEuler's check of its sweep count. Convergence orders measured on chains are in test_rollout.py and
test_stability.py."""

import diffrax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.integrate import interval, solvers


def acrobot():
    return lg.systems.acrobot()


@pytest.mark.parametrize(
    "solver", ["rk4", lg.RK4, diffrax.Kvaerno5(), None], ids=["str", "class", "implicit", "None"]
)
def test_not_a_solver(solver):
    z = jnp.zeros(2)
    with pytest.raises(TypeError, match=r"solver must be"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), 0.01, solver)
    with pytest.raises(TypeError, match=r"solver must be"):
        lg.step(acrobot(), z, z, jnp.zeros(1), 0.01, solver)


def test_momentum_euler_rejects_bad_iterations():
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="iterations"):
            lg.MomentumEuler(iterations=bad)


# ------------------------------------------------------------------ RK4's tableau


def test_rk4_tableau_satisfies_the_order_conditions():
    """Classical RK4 (Butcher 1.0, 1/2, 1/2, 1; weights 1/6, 1/3, 1/3, 1/6) and the eight order conditions up to
    order 4, exactly in binary fractions (every coefficient is a dyadic rational or a sum of thirds and sixths; the
    sums are compared to 1e-15)."""
    t = lg.RK4.tableau
    a = np.zeros((4, 4))
    for i, row in enumerate(t.a_lower):
        a[i + 1, : i + 1] = row
    b, c = np.asarray(t.b_sol), np.concatenate([[0.0], t.c])
    np.testing.assert_array_equal(a, [[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]])
    np.testing.assert_allclose(b, [1 / 6, 1 / 3, 1 / 3, 1 / 6], rtol=0, atol=1e-16)
    np.testing.assert_allclose(c, a.sum(1), rtol=0, atol=0)  # row-sum condition
    conditions = {
        "b.1 = 1": (b.sum(), 1),
        "b.c = 1/2": (b @ c, 1 / 2),
        "b.c^2 = 1/3": (b @ c**2, 1 / 3),
        "b.Ac = 1/6": (b @ a @ c, 1 / 6),
        "b.c^3 = 1/4": (b @ c**3, 1 / 4),
        "b.(c Ac) = 1/8": (b @ (c * (a @ c)), 1 / 8),
        "b.Ac^2 = 1/12": (b @ a @ c**2, 1 / 12),
        "b.AAc = 1/24": (b @ a @ a @ c, 1 / 24),
    }
    for name, (got, want) in conditions.items():
        assert abs(got - want) <= 1e-15, name
    assert not np.any(np.asarray(t.b_error))  # no embedded error estimate: fixed steps only


def _classical_rk4(f, t0, y0, h):
    """The classical formulas, k1..k4, written out."""
    k1 = f(t0, y0)
    k2 = f(t0 + h / 2, y0 + h / 2 * k1)
    k3 = f(t0 + h / 2, y0 + h / 2 * k2)
    k4 = f(t0 + h, y0 + h * k3)
    return y0 + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def test_rk4_in_diffrax_is_the_classical_rk4_step():
    """``lg.RK4()`` run by diffrax's own explicit Runge-Kutta step (``diffeqsolve``, 3 fixed steps) on a nonlinear,
    time-dependent ODE equals three classical RK4 steps written by hand, to float64 round-off (a few ulps of the
    O(1) state: 1e-14)."""

    def f(t, y, args=None):
        return jnp.stack([y[1], -jnp.sin(y[0]) + 0.3 * jnp.cos(2.0 * t) - 0.1 * y[1] * y[0] ** 2])

    y0, h, steps = jnp.array([0.7, -0.4]), 0.13, 3
    sol = diffrax.diffeqsolve(diffrax.ODETerm(f), lg.RK4(), t0=0.0, t1=h * steps, dt0=h, y0=y0,
                              stepsize_controller=diffrax.ConstantStepSize(), saveat=diffrax.SaveAt(t1=True))
    want = y0
    for k in range(steps):
        want = _classical_rk4(f, k * h, want, h)
    np.testing.assert_allclose(np.asarray(sol.ys[-1]), np.asarray(want), rtol=0, atol=1e-14)
    # the same step is fourth order: two steps of h/2 (each 2^5 smaller) leave about 2^4 less error than one of h
    exact = diffrax.diffeqsolve(diffrax.ODETerm(f), diffrax.Dopri8(), t0=0.0, t1=0.4, dt0=1e-3, y0=y0,
                                stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13)).ys[-1]
    e1 = float(jnp.max(jnp.abs(_classical_rk4(f, 0.0, y0, 0.4) - exact)))
    half = _classical_rk4(f, 0.0, y0, 0.2)
    e2 = float(jnp.max(jnp.abs(_classical_rk4(f, 0.2, half, 0.2) - exact)))
    assert 16 * 0.7 < e1 / e2 < 16 * 1.5, e1 / e2  # measured 17.2


# ------------------------------------------------------------------ orders and refusals


def test_orders_and_adaptivity():
    """The classical orders (RK4 4, Euler 1, Tsit5 5, Dopri5 5, Dopri8 8, both symplectic Eulers 1) and which
    solvers carry an embedded error estimate (only those may take rtol/atol)."""
    want = {lg.RK4(): (4, False), lg.Euler(): (1, False), lg.Tsit5(): (5, True), lg.Dopri5(): (5, True),
            lg.Dopri8(): (8, True), lg.SemiImplicitEuler(): (1, False), lg.MomentumEuler(): (1, False)}
    assert {type(s) for s in want} == set(solvers.SOLVERS)
    for solver, (order, adaptive) in want.items():
        assert (solvers.order(solver), solvers.is_adaptive_capable(solver)) == (order, adaptive), solver


def test_unknown_solver_error_names_every_allowed_solver():
    for bad in ("rk4", None, diffrax.Kvaerno5(), 3):
        with pytest.raises(TypeError) as err:
            interval.check_solver(bad)
        message = str(err.value)
        for cls in solvers.SOLVERS:
            assert f"lagrange.{cls.__name__}()" in message
        assert repr(bad) in message
    # a class, not an instance: the message says how to write it
    for cls in solvers.SOLVERS:
        with pytest.raises(TypeError, match=rf"got the class {cls.__name__}; write {cls.__name__}\(\)"):
            interval.check_solver(cls)
    for solver in (cls() for cls in solvers.SOLVERS):
        interval.check_solver(solver)  # accepted: returns None
    interval.check_solver(diffrax.Heun())  # any other explicit diffrax Runge-Kutta method


def test_the_old_name_of_momentum_euler_still_works_with_a_warning():
    """``SymplecticEuler`` was renamed ``MomentumEuler`` (textbooks call semi-implicit Euler symplectic Euler too):
    the old name, from ``lagrange`` or ``lagrange.integrate.solvers``, gives the same class and warns at the caller's
    line; an unknown name is still an AttributeError naming its module."""
    for module in (lg, solvers):
        with pytest.warns(DeprecationWarning, match="SymplecticEuler is renamed lagrange.MomentumEuler") as rec:
            old = module.SymplecticEuler
        assert old is lg.MomentumEuler and rec[0].filename == __file__
    assert "SymplecticEuler" not in lg.__all__ and "MomentumEuler" in lg.__all__
    for module, name in ((lg, "'lagrange'"), (solvers, "'lagrange.integrate.solvers'")):
        with pytest.raises(AttributeError, match=f"module {name} has no attribute 'SymplecticEuIer'"):
            module.SymplecticEuIer  # noqa: B018 (a capital I for the l: a typo)
