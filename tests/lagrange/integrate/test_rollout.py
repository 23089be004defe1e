"""Time integration: conservation laws, measured convergence order, agreement with diffrax's own
``diffeqsolve``, adaptive accuracy, and gradients through ``simulate`` against finite differences.

Tolerances follow from the solver. A method of order ``p`` with step ``h`` on a system whose
fastest linearised frequency is ``omega`` makes a local error ~ ``(h omega)^(p+1)`` relative to
the motion's scale per step, so over a horizon ``T`` (``T / h`` steps) the energy error is bounded
by ``~ C omega T (h omega)^p E_scale`` with ``E_scale = sum m g l`` (the potential-energy range).
We take ``C = 1`` and check the measured error against that bound; float64 round-off
(~1e-16 E_scale per step) is far below it for every solver used. Measured on the acrobot
(omega = 7.19 rad/s, E_scale = 98 J, h = 0.01 s, 2 s): RK4 2.5e-5 J (bound 3.8e-2), Tsit5 1.1e-7
(2.7e-3), Dopri5 2.1e-7 (2.7e-3), Dopri8 2.1e-12 (1.0e-6). C = 1 is conservative (by 10^3 to
10^6 here), so the energy test also checks that the error falls like h^p.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import lagrange as lg
from lagrange.planar.lower import lower as planar
from tests.helpers import rebuilt, states_equal


ERK = [lg.RK4(), lg.Euler(), lg.Tsit5(), lg.Dopri5(), lg.Dopri8()]
ALL = ERK + [lg.SemiImplicitEuler(), lg.MomentumEuler()]


def name(solver):
    return type(solver).__name__


def omega_max(chain):
    """Fastest linearised frequency about the hanging equilibrium [rad/s]."""
    z = jnp.zeros(chain.nv)
    K = jax.jacfwd(lambda q: lg.gravity_forces(chain, q))(z)
    return float(np.sqrt(np.max(np.real(np.linalg.eigvals(np.linalg.solve(lg.mass_matrix(chain, z), K))))))


def energy_scale(chain):
    return float(jnp.sum(chain.mass) * planar(chain).gravity * jnp.sum(planar(chain).length))


@jax.jit
def _total_energy(chain, q, qd):
    kin, pot = lg.energy(chain, q, qd)
    return kin + pot


def total_energy(chain, traj):
    return np.asarray(jax.vmap(lambda q, qd: _total_energy(chain, q, qd))(traj.q, traj.qd))


# ------------------------------------------------------------------ energy


# (solver, steps h [s]): the error bound is checked at h = 0.01 s, the order over the halvings
ENERGY_CASES = [
    (lg.RK4(), (0.02, 0.01, 0.005)),
    (lg.Tsit5(), (0.02, 0.01, 0.005)),
    (lg.Dopri5(), (0.02, 0.01, 0.005)),
    (lg.Dopri8(), (0.04, 0.02, 0.01)),  # at 0.005 Dopri8's error (~1e-14 J) is round-off
]


@pytest.mark.parametrize("solver,steps", ENERGY_CASES, ids=[name(s) for s, _ in ENERGY_CASES])
def test_energy_conserved_without_damping(solver, steps):
    """Acrobot from q = (1, 0.5) at rest, u = 0, no damping, 2 s: the largest energy error
    (i) is below the C = 1 bound at h = 0.01 s and (ii) shrinks by at least 2^(p - 0.5) per halving
    of h, so losing one order fails (ii) even where (i) is conservative.
    Measured log2 ratios: RK4 4.06, 3.79; Tsit5 5.22, 5.43; Dopri5 5.59, 5.19; Dopri8 10.5, 8.75."""
    chain = lg.systems.acrobot()
    q0, qd0, u, T = jnp.array([1.0, 0.5]), jnp.zeros(2), jnp.zeros(1), 2.0

    def E(q, qd):
        kin, pot = lg.energy(chain, q, qd)
        return kin + pot

    @jax.jit
    def max_energy_error(n):  # n and h traced: one compilation for every step size
        h, E0 = T / n, E(q0, qd0)

        def body(i, carry):
            q, qd, worst = carry
            q, qd = lg.step(chain, q, qd, u, h, solver)
            return q, qd, jnp.maximum(worst, jnp.abs(E(q, qd) - E0))

        return jax.lax.fori_loop(0, n, body, (q0, qd0, jnp.zeros(())))[2]

    errs = {h: float(max_energy_error(int(round(T / h)))) for h in steps}
    w, p = omega_max(chain), lg.solvers.order(solver)
    bound = w * T * (0.01 * w) ** p * energy_scale(chain)  # C = 1, see the module docstring
    assert 0.01 * w < 0.1  # the estimate assumes the asymptotic regime h omega << 1
    assert errs[0.01] <= bound, f"{name(solver)}: energy error {errs[0.01]:.3g} J > bound {bound:.3g} J"
    e = [errs[h] for h in steps]
    rates = np.log2(np.array(e[:-1]) / np.array(e[1:]))
    assert np.all(rates >= p - 0.5), f"{name(solver)}: energy error rates {rates}, order {p}; errors {e}"


def test_semi_implicit_euler_energy_bounded_not_drifting():
    """Symplectic Euler: the energy error oscillates with amplitude O(h omega) E_scale and does not
    grow over 20 s (2000 steps, 12 periods of the pendulum, whose modified energy is exactly
    conserved); explicit Euler on the same problem drifts (so the check can fail).
    Measured: SIE max error 0.0414 J in the first and in the last quarter; Euler 1.8 J -> 8.3 J."""
    chain = lg.systems.pendulum()
    dt, steps = 0.01, 2000
    q0, qd0 = jnp.array([1.0]), jnp.array([0.0])
    w = omega_max(chain)

    def errors(solver):
        traj = lg.simulate(chain, q0, qd0, jnp.zeros((steps, 1)), dt, solver)
        E = total_energy(chain, traj)
        return np.abs(E - E[0])

    e = errors(lg.SemiImplicitEuler())
    quarter = steps // 4
    assert np.max(e) <= dt * w * energy_scale(chain)
    assert np.max(e[-quarter:]) <= 1.05 * np.max(e[:quarter])  # bounded: no secular growth
    e_euler = errors(lg.Euler())
    assert np.max(e_euler[-quarter:]) > 3 * np.max(e_euler[:quarter])  # explicit Euler grows


def test_energy_decreases_with_damping():
    """With joint damping b and u = 0, dE/dt = -b |qd|^2 < 0: strictly decreasing at every step, and
    the total loss equals the dissipated work (trapezoidal rule, error O(dt^2))."""
    b = 0.3
    chain = lg.systems.acrobot(damping=b)
    dt, steps = 0.01, 300
    traj = lg.simulate(chain, jnp.array([1.0, 0.5]), jnp.array([0.5, -0.5]), jnp.zeros((steps, 1)), dt, lg.RK4())
    E = total_energy(chain, traj)
    # per step the loss is ~ dt b |qd|^2 ~ 1e-3 J, RK4's energy error per step ~ 1e-8 J
    assert np.all(np.diff(E) < 0)
    power = b * np.sum(np.asarray(traj.qd) ** 2, axis=1)
    work = float(np.sum(0.5 * dt * (power[1:] + power[:-1])))
    loss = float(E[0] - E[-1])
    assert loss > 0.5
    assert abs(loss - work) <= 1e-3 * loss  # trapezoid: (T dt^2 / 12) max|d2P/dt2| ~ 1e-4 relative here


# ------------------------------------------------------------------ convergence order


# (solver, numbers of steps over 1 s); step sizes are in the asymptotic range and the smallest
# error stays > 2e-13, ten times the reference's own error (2e-14: rtol 1e-13 vs 1e-14, measured).
ORDER_CASES = [
    (lg.Euler(), [256, 512, 1024, 2048]),
    (lg.SemiImplicitEuler(), [256, 512, 1024, 2048]),
    (lg.MomentumEuler(), [256, 512, 1024, 2048]),
    (lg.RK4(), [32, 64, 128, 256]),
    (lg.Tsit5(), [16, 32, 64, 128]),
    (lg.Dopri5(), [32, 64, 128, 256]),
    (lg.Dopri8(), [12, 16, 24, 32]),
]


@pytest.fixture(scope="module")
def order_problem():
    """The cartpole swinging (non-chaotic, smooth) for 1 s under a constant control, and its
    reference end state from adaptive Dopri8 at rtol = atol = 1e-13."""
    chain = lg.systems.cartpole()
    q0, qd0, u, T = jnp.array([0.0, 1.0]), jnp.array([0.5, 0.3]), jnp.array([0.1]), 1.0
    ref = lg.simulate(chain, q0, qd0, u[None], T, lg.Dopri8(), substeps=64, rtol=1e-13, atol=1e-13)
    return chain, q0, qd0, u, T, jnp.concatenate([ref.q[-1], ref.qd[-1]])


@pytest.mark.parametrize("solver,steps", ORDER_CASES, ids=[name(s) for s, _ in ORDER_CASES])
def test_convergence_order(order_problem, solver, steps):
    """Least-squares slope of log(error) against log(h) over halving steps.

    Accepted: p - 0.3 <= slope <= p + 0.9. The lower bound is the real test (a wrong tableau or a
    dropped stage loses at least one order). The upper allowance exists because Tsit5's and the
    Dormand-Prince pairs' leading error constants are tuned small, so the next order still
    contributes at any step whose error is above float64 round-off (measured slopes: Euler 1.01,
    SemiImplicitEuler 1.00, RK4 3.99, Tsit5 5.83, Dopri5 5.2, Dopri8 7.8)."""
    chain, q0, qd0, u, T, y_ref = order_problem

    @jax.jit
    def error(n):  # one compilation for all step counts: n and h are traced
        h = T / n
        q, qd = jax.lax.fori_loop(0, n, lambda i, c: lg.step(chain, *c, u, h, solver), (q0, qd0))
        return jnp.max(jnp.abs(jnp.concatenate([q, qd]) - y_ref))

    errs = np.array([float(error(n)) for n in steps])
    slope = np.polyfit(np.log(T / np.array(steps)), np.log(errs), 1)[0]
    p = lg.solvers.order(solver)
    assert errs[-1] > 2e-13, errs  # above the reference's own error
    assert p - 0.3 <= slope <= p + 0.9, f"{name(solver)}: measured order {slope:.2f}, theory {p}; errors {errs}"


# ------------------------------------------------------------------ paths agree


@pytest.mark.parametrize("solver", ERK, ids=name)
def test_fixed_step_path_equals_diffeqsolve(solver):
    """The unrolled tableau path equals diffrax.diffeqsolve with RecursiveCheckpointAdjoint: same
    arithmetic in a different order, so round-off only (40 steps x ~1e-16 x |state| ~ 1e-14)."""
    chain = lg.systems.double_cartpole()
    rng = np.random.default_rng(0)
    controls = jnp.asarray(rng.uniform(-0.1, 0.1, (20, 1)))
    q0, qd0 = jnp.array([0.1, 2.5, -0.4]), jnp.array([0.3, -0.5, 0.8])
    a = lg.simulate(chain, q0, qd0, controls, 0.01, solver, substeps=2)
    b = lg.simulate(chain, q0, qd0, controls, 0.01, solver, substeps=2, adjoint=diffrax.RecursiveCheckpointAdjoint())
    scale = max(1.0, float(jnp.max(jnp.abs(a.qd))))
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(a.qd, b.qd, rtol=0, atol=1e-13 * scale)
    assert float(jnp.max(jnp.abs(a.q[-1] - q0))) > 0.01  # it moved


def test_adaptive_accuracy(order_problem):
    """Adaptive Dopri5 and Tsit5 at rtol = atol = 1e-8 end within 1e-6 of the reference: a PI
    controller bounds the local error per step by the tolerance, and over the ~30 accepted steps
    of this problem the global error stays within 100 x tol."""
    chain, q0, qd0, u, T, y_ref = order_problem
    runs = ((lg.Dopri5(), 1e-8), (lg.Tsit5(), 1e-8), (lg.Dopri5(), 1e-5))
    # the three adaptive rollouts in one compiled program (op by op, each compiles its own loop anyway)
    dopri5, tsit5, loose = jax.jit(lambda q0, qd0, u: [
        lg.simulate(chain, q0, qd0, u[None], T, solver, rtol=tol, atol=tol) for solver, tol in runs])(q0, qd0, u)
    for solver, traj in ((lg.Dopri5(), dopri5), (lg.Tsit5(), tsit5)):
        err = float(jnp.max(jnp.abs(jnp.concatenate([traj.q[-1], traj.qd[-1]]) - y_ref)))
        assert err < 1e-6, (name(solver), err)
    # tightening the tolerance improves it (loose: Dopri5 at rtol = atol = 1e-5)
    err_loose = float(jnp.max(jnp.abs(jnp.concatenate([loose.q[-1], loose.qd[-1]]) - y_ref)))
    assert err_loose > 10 * err


# ------------------------------------------------------------------ gradients


def _acrobot_problem():
    chain = lg.systems.acrobot()
    rng = np.random.default_rng(1)
    controls = jnp.asarray(rng.uniform(-0.5, 0.5, (15, 1)))
    return chain, jnp.array([0.3, -0.2]), jnp.array([0.1, 0.4]), controls


@pytest.mark.parametrize("solver", [lg.RK4(), lg.SemiImplicitEuler(), lg.MomentumEuler()], ids=name)
def test_gradients_through_simulate(solver):
    """d(final state)/d(initial state, controls, link masses) against central differences
    (check_grads: step 1e-4, so truncation ~1e-8 and round-off ~1e-12 relative, well inside its
    float64 tolerance 1e-5), forward and reverse mode."""
    chain, q0, qd0, controls = _acrobot_problem()

    def final(q0, qd0, controls, mass):
        c = rebuilt(chain, mass=mass)
        traj = lg.simulate(c, q0, qd0, controls, 0.02, solver, substeps=2)
        return jnp.concatenate([traj.q[-1], traj.qd[-1]])

    check_grads(jax.jit(final), (q0, qd0, controls, chain.mass), order=1, modes=("fwd", "rev"))


@pytest.mark.parametrize("hold", [False, True], ids=["own_M", "held_M"])
def test_checkpointed_substeps_change_no_step_and_no_gradient(hold):
    """``SemiImplicitEuler(checkpoint_substeps=True)`` recomputes each substep in the backward pass (more remats in
    the gradient's program than without the flag) and gives the same trajectory and the same gradient to
    round-off."""
    chain, q0, qd0, controls = _acrobot_problem()

    def final(controls, checkpoint):
        solver = lg.SemiImplicitEuler(hold_mass_matrix=hold, checkpoint_substeps=checkpoint)
        traj = lg.simulate(chain, q0, qd0, controls, 0.02, solver, substeps=4)
        return jnp.concatenate([traj.q[-1], traj.qd[-1]]) @ jnp.array([1.0, 2.0, 3.0, 4.0])

    remats = [str(jax.make_jaxpr(jax.grad(final), static_argnums=1)(controls, c)).count("remat")
              for c in (False, True)]
    assert remats[1] > remats[0]
    (v0, g0), (v1, g1) = (jax.jit(jax.value_and_grad(final), static_argnums=1)(controls, c) for c in (False, True))
    np.testing.assert_allclose(float(v1), float(v0), rtol=1e-14)
    np.testing.assert_allclose(np.asarray(g1), np.asarray(g0), rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(g0))))


def test_the_mass_matrix_refreshed_every_k_substeps_is_k_substeps_held_each():
    """``SemiImplicitEuler(hold_mass_matrix=True, mass_matrix_every=k)`` (DFlex's ``MM_caching_frequency``): 4
    substeps refreshed every 2 are two intervals of half the length held each, bit for bit; refreshed every substep
    they are the unheld step; ``k`` must divide the substeps and needs ``hold_mass_matrix``."""
    chain, q0, qd0, controls = _acrobot_problem()
    held = lg.SemiImplicitEuler(hold_mass_matrix=True)

    def every(k, substeps=4):
        solver = lg.SemiImplicitEuler(hold_mass_matrix=True, mass_matrix_every=k)
        return lg.simulate(chain, q0, qd0, controls, 0.02, solver, substeps=substeps)

    halves = lg.simulate(chain, q0, qd0, jnp.repeat(controls, 2, axis=0), 0.01, held, substeps=2)
    refreshed = every(2)
    np.testing.assert_array_equal(refreshed.q[-1], halves.q[-1])
    np.testing.assert_array_equal(refreshed.qd[-1], halves.qd[-1])
    assert not np.array_equal(refreshed.qd[-1], every(4).qd[-1])  # once per interval: another step
    own = lg.simulate(chain, q0, qd0, controls, 0.02, lg.SemiImplicitEuler(), substeps=4)
    np.testing.assert_allclose(every(1).qd[-1], own.qd[-1], rtol=1e-12)
    with pytest.raises(ValueError, match=r"mass_matrix_every=3 must divide substeps=4"):
        every(3)
    with pytest.raises(ValueError, match=r"mass_matrix_every needs hold_mass_matrix=True"):
        lg.SemiImplicitEuler(mass_matrix_every=2)
    with pytest.raises(ValueError, match=r"mass_matrix_every must be None or an integer >= 1, got 0"):
        lg.SemiImplicitEuler(hold_mass_matrix=True, mass_matrix_every=0)


def test_gradients_through_diffrax_adjoint():
    """The same through diffeqsolve with RecursiveCheckpointAdjoint (reverse mode), and equal to the
    fixed-step path's gradient to round-off."""
    chain, q0, qd0, controls = _acrobot_problem()

    def final(controls, mass, adjoint):
        c = rebuilt(chain, mass=mass)
        traj = lg.simulate(c, q0, qd0, controls, 0.02, lg.RK4(), substeps=2, adjoint=adjoint)
        return jnp.sum(jnp.sin(traj.q[-1])) + jnp.sum(traj.qd[-1] ** 2)

    adj = diffrax.RecursiveCheckpointAdjoint()
    f = jax.jit(lambda c, m: final(c, m, adj))
    check_grads(f, (controls, chain.mass), order=1, modes=("rev",))
    g_adj = jax.grad(f, argnums=(0, 1))(controls, chain.mass)
    g_fix = jax.jit(jax.grad(lambda c, m: final(c, m, None), argnums=(0, 1)))(controls, chain.mass)
    for a, b in zip(g_adj, g_fix):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("solver, kw", [
    (lg.SemiImplicitEuler(), {}), (lg.RK4(), dict(substeps=3)), (lg.Tsit5(), dict(rtol=1e-6, atol=1e-6)),
    (lg.RK4(), dict(adjoint=diffrax.RecursiveCheckpointAdjoint())),
], ids=["semi-implicit Euler", "RK4 x3", "Tsit5 adaptive", "RK4 diffeqsolve"])
def test_a_float32_chain_runs_in_float32_under_64_bit_mode(solver, kw):
    """A chain cast to float32 rolls out in float32 with JAX's 64-bit mode on (as here), through the unrolled steps and
    through diffeqsolve (whose times once came in float64 and promoted the state: its scan refused the carry), with
    its gradient; 15 intervals meet float64's to float32 round-off: measured <= 4.9e-7 of max|qd| on the fixed steps
    and 1.2e-6 adaptive (float32 also picks other steps there, at tolerances of 1e-6); bound 50 x float32's 1.2e-7."""
    chain, q0, qd0, controls = _acrobot_problem()
    low = lg.astype(chain, jnp.float32)

    def run(c, qd0, dtype):
        return lg.simulate(c, q0.astype(dtype), qd0, controls.astype(dtype), 0.02, solver, **kw)

    def final(v):
        tr = run(low, v, jnp.float32)
        return jnp.sum(tr.q[-1] ** 2), tr

    exact = run(chain, qd0, jnp.float64)
    (_, tr), g = jax.value_and_grad(final, has_aux=True)(qd0.astype(jnp.float32))
    assert tr.q.dtype == tr.qd.dtype == g.dtype == jnp.float32 and bool(jnp.all(jnp.isfinite(g)))
    scale = max(1.0, float(jnp.max(jnp.abs(exact.qd))))
    assert float(jnp.max(jnp.abs(tr.q - exact.q))) <= 6e-6 * scale
    assert float(jnp.max(jnp.abs(tr.qd - exact.qd))) <= 6e-6 * scale


def test_astype_casts_floating_arrays_only_and_refuses_other_types():
    """lg.astype casts every floating array of a model or states and leaves integer arrays, Python numbers and static
    fields alone; a non-floating type, and float64 with the 64-bit mode off, are refused by name."""
    chain = lg.systems.acrobot()
    low = lg.astype(chain, jnp.float32)
    floats = [a for a in jax.tree.leaves(low) if eqx.is_inexact_array(a)]
    assert floats and all(a.dtype == jnp.float32 for a in floats)
    assert jax.tree.structure(low) == jax.tree.structure(chain)
    assert float(jnp.max(jnp.abs(low.mass - chain.mass))) == 0.0  # exactly representable parameters
    q, index, scale = lg.astype((jnp.ones(2), jnp.arange(3), 2.0), jnp.float32)
    assert q.dtype == jnp.float32 and index.dtype == jnp.arange(3).dtype and scale == 2.0
    assert lg.astype(low, jnp.float64).mass.dtype == jnp.float64
    with pytest.raises(ValueError, match="dtype must be a floating type .* got int32"):
        lg.astype(chain, jnp.int32)
    for bad in ("nonsense", None):  # jnp.dtype: a TypeError, and float64 for None
        with pytest.raises(ValueError, match=f"dtype must be a floating type .* got {bad!r}"):
            lg.astype(chain, bad)
    with jax.enable_x64(False), pytest.raises(ValueError, match="float64 needs JAX's 64-bit mode"):
        lg.astype(chain, jnp.float64)


# ------------------------------------------------------------------ policies and step


def test_policy_callable_matches_manual_loop():
    """A feedback policy(t, q, qd) inside simulate equals stepping by hand with u = policy(k dt, q, qd)."""
    chain = lg.systems.cartpole()
    K = jnp.array([0.3, -2.0, 0.5, -0.4])

    def policy(t, q, qd):
        return jnp.tanh(K @ jnp.concatenate([q, qd]) + jnp.sin(3.0 * t))[None]

    q0, qd0, dt, steps = jnp.array([0.0, 0.5]), jnp.array([0.0, 0.0]), 0.04, 25
    traj = lg.simulate(chain, q0, qd0, policy, dt, lg.RK4(), substeps=4, steps=steps)
    assert traj.q.shape == (steps + 1, 2) and traj.u.shape == (steps, 1)
    q, qd, us = q0, qd0, []
    step = jax.jit(lambda q, qd, u: lg.step(chain, q, qd, u, dt, lg.RK4(), substeps=4))
    for k in range(steps):
        u = policy(k * dt, q, qd)
        us.append(u)
        q, qd = step(q, qd, u)
    np.testing.assert_allclose(traj.u, jnp.stack(us), rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.q[-1], q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.qd[-1], qd, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.t, dt * np.arange(steps + 1), rtol=0, atol=1e-15)
    # open-loop replay of the recorded controls gives the same trajectory
    replay = lg.simulate(chain, q0, qd0, traj.u, dt, lg.RK4(), substeps=4)
    np.testing.assert_allclose(replay.q, traj.q, rtol=0, atol=1e-12)


@pytest.mark.parametrize("solver", ALL, ids=name)
def test_step_equals_one_interval_of_simulate(solver):
    chain = lg.systems.acrobot(damping=0.2)  # damping: SemiImplicitEuler treats it implicitly
    q, qd, u, dt = jnp.array([0.3, -1.2]), jnp.array([0.5, 2.0]), jnp.array([0.4]), 0.02
    q1, qd1 = jax.jit(lambda *a: lg.step(chain, *a, dt, solver, substeps=3))(q, qd, u)
    traj = jax.jit(lambda *a: lg.simulate(chain, *a, dt, solver, substeps=3))(q, qd, u[None])
    np.testing.assert_allclose(q1, traj.q[1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(qd1, traj.qd[1], rtol=0, atol=1e-14)
    # batch dims: a (4, n) batch of states steps like each state on its own
    rng = np.random.default_rng(2)
    Q, QD, U = (jnp.asarray(rng.uniform(-1, 1, (4, k))) for k in (2, 2, 1))
    batched = jax.jit(lambda *a: lg.step(chain, *a, dt, solver, substeps=3))(Q, QD, U)
    single = jax.jit(jax.vmap(lambda a, b, c: lg.step(chain, a, b, c, dt, solver, substeps=3)))(Q, QD, U)
    for x, y in zip(batched, single):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-13)


def test_semi_implicit_euler_is_one_mujoco_step():
    """SemiImplicitEuler with damping: qd' = qd + h (M + h D)^-1 (B u - C qd - T - D qd), q' = q + h qd'."""
    chain = lg.systems.acrobot(damping=0.7)
    q, qd, u, h = jnp.array([0.3, -1.2]), jnp.array([0.5, 2.0]), jnp.array([0.4]), 0.05
    M = lg.mass_matrix(chain, q) + h * jnp.diag(planar(chain).damping)
    rhs = lg.actuation_matrix(chain) @ u - lg.bias_forces(chain, q, qd)
    qd1 = qd + h * jnp.linalg.solve(M, rhs)
    q1 = q + h * qd1
    got = lg.step(chain, q, qd, u, h, lg.SemiImplicitEuler())
    np.testing.assert_allclose(got[0], q1, rtol=0, atol=1e-14)
    np.testing.assert_allclose(got[1], qd1, rtol=0, atol=1e-14)


def test_momentum_euler_is_semi_implicit_euler_where_m_is_constant():
    """With a constant mass matrix dT/dq = 0, so symplectic Euler in momenta and the velocity-form
    semi-implicit Euler are the same step, damping included (both treat it implicitly): a damped
    pendulum and a two-stage prismatic chain, 200 steps, equal to round-off."""
    from lagrange.chain import Chain, Link

    chains = [Chain([Link("revolute", 1.3, 0.8, damping=0.4, gear=1.0)]),
              Chain([Link("prismatic", 1.0, 0.5, axis=0.3, damping=0.2, gear=2.0),
                     Link("prismatic", 2.0, 0.5, axis=-1.1, gear=1.0)])]
    for chain in chains:
        q0, qd0 = jnp.full(chain.nv, 0.7), jnp.full(chain.nv, -0.5)
        us = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, (200, chain.m)))
        a = lg.simulate(chain, q0, qd0, us, 0.01, lg.MomentumEuler())
        b = lg.simulate(chain, q0, qd0, us, 0.01, lg.SemiImplicitEuler())
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.qd, b.qd, rtol=0, atol=1e-12)


def test_momentum_euler_solves_its_implicit_equation():
    """The default sweeps solve ``(M + h D) v = M qd + h (B u - T + dT/dq(q, v))`` to round-off on
    64 random acrobot states with speeds ~ N(0, 10) rad/s at h = 1e-3 (measured residual ~1e-13
    rad/s against 40 sweeps; 4 sweeps leave ~1e-6), and the returned qd' is M(q')^-1 M(q) v."""
    chain = lg.systems.acrobot(damping=0.3)
    rng = np.random.default_rng(3)
    q, qd = jnp.asarray(rng.uniform(-3, 3, (64, 2))), jnp.asarray(10 * rng.normal(size=(64, 2)))
    u, h = jnp.asarray(rng.uniform(-1, 1, (64, 1))), 1e-3

    @jax.jit  # one compiled program: op by op, the sweeps and the energy's gradient cost ~3x its compilation
    def library(q, qd, u):
        q1, qd1 = lg.step(chain, q, qd, u, h, lg.MomentumEuler())
        v = (q1 - q) / h
        kin_grad = jax.vmap(jax.grad(lambda q, v: lg.energy(chain, q, v)[0]))(q, v)
        loose = lg.step(chain, q, qd, u, h, lg.MomentumEuler(iterations=4))[1]
        return q1, qd1, v, kin_grad, lg.mass_matrix(chain, q), lg.mass_matrix(chain, q1), loose

    q1, qd1, v, kin_grad, M, M1, loose = library(q, qd, u)
    lhs = jnp.einsum("bij,bj->bi", M + h * jnp.diag(planar(chain).damping), v)
    rhs = (jnp.einsum("bij,bj->bi", M, qd)
           + h * (u @ lg.actuation_matrix(chain).T - lg.gravity_forces(chain, q) + kin_grad))
    scale = float(jnp.max(jnp.abs(rhs)))
    assert float(jnp.max(jnp.abs(lhs - rhs))) <= 1e-13 * scale
    p1 = jnp.einsum("bij,bj->bi", M1, qd1)
    np.testing.assert_allclose(p1, jnp.einsum("bij,bj->bi", M, v), rtol=0, atol=1e-12 * scale)
    assert float(jnp.max(jnp.abs(loose - qd1))) > 1e-9  # the sweep count matters: the check can fail


# ------------------------------------------------------------------ arguments


def test_arguments_are_converted_or_refused_by_name():
    """Integers and lower-precision floats are converted to the chain's float dtype (float64 here), which gives the
    float64 run's numbers; booleans and complex numbers, a zero-length or negative or fractional number of
    intervals, shapes that do not match the chain and a boolean ``dt`` are refused, naming the argument."""
    chain = lg.systems.acrobot()
    q0, qd0, us = jnp.array([0.0, 1.0]), jnp.zeros(2), jnp.zeros((3, 1))
    ref = lg.simulate(chain, q0, qd0, us, 0.01)
    for q in (np.array([0, 1]), jnp.array([0.0, 1.0], jnp.float16), jnp.array([0.0, 1.0], jnp.float32)):
        tr = lg.simulate(chain, q, qd0, np.zeros((3, 1), np.int32), 0.01)
        assert tr.q.dtype == tr.u.dtype == jnp.float64
        np.testing.assert_array_equal(tr.q, ref.q)  # 0 and 1 are exact in every one of these types
    np.testing.assert_array_equal(lg.simulate(chain, q0, qd0, None, 0.01, steps=3).q, ref.q)  # unactuated: u = 0
    q1, qd1 = lg.step(chain, np.array([0, 1]), np.zeros(2, np.int64), np.zeros(1, np.int8), 0.01)
    assert q1.dtype == jnp.float64 and states_equal((q1, qd1), lg.step(chain, q0, qd0, us[0], 0.01))
    policy = lambda t, q, qd: jnp.zeros(1, jnp.int32)  # noqa: E731
    np.testing.assert_array_equal(lg.simulate(chain, q0, qd0, policy, 0.01, steps=3).q, ref.q)
    refused = [
        (dict(q0=jnp.array([True, False])), TypeError, r"q0 must hold real numbers .* got dtype bool"),
        (dict(qd0=jnp.array([1j, 0])), TypeError, r"qd0 must hold real numbers .* got dtype complex"),
        (dict(controls=jnp.zeros((3, 1), bool)), TypeError, r"controls must hold real numbers"),
        (dict(controls=lambda t, q, qd: jnp.ones(1, bool), steps=2), TypeError, r"the policy's u must hold real"),
        (dict(controls=jnp.zeros((0, 1))), ValueError, r"at least one control interval: shape \(T >= 1, 1\), got "
                                                       r"\(0, 1\)"),
        (dict(controls=None, steps=-1), ValueError, r"steps must be None or an integer >= 1 .* got -1"),
        (dict(controls=None, steps=0), ValueError, r"steps must be None or an integer >= 1 .* got 0"),
        (dict(controls=None, steps=2.5), ValueError, r"steps must be None or an integer >= 1 .* got 2\.5"),
        (dict(steps=True), ValueError, r"steps must be None or an integer >= 1 .* got True"),
        (dict(steps=4), ValueError, r"steps=4 disagrees with controls of length 3"),
        (dict(dt=True), TypeError, r"dt must be a positive real number of seconds, got True"),
        (dict(dt=np.bool_(True)), TypeError, r"dt must be a positive real number of seconds"),
        (dict(dt=0.01j), TypeError, r"dt must be a positive real number of seconds"),
        (dict(dt=-0.01), ValueError, r"dt must be a finite number > 0 seconds"),
        (dict(q0=jnp.zeros(3)), ValueError, r"q0 must have shape \(2,\) for this tree, got \(3,\)"),
        (dict(max_steps=0), ValueError, r"max_steps must be an integer >= 1 \(solver steps per interval\), got 0"),
        (dict(controls=jnp.zeros((3, 2))), ValueError, r"controls must have shape \(T, 1\) for this tree"),
    ]
    for change, error, message in refused:
        args = {**dict(q0=q0, qd0=qd0, controls=us, dt=0.01), **change}
        with pytest.raises(error, match=message):
            lg.simulate(chain, args.pop("q0"), args.pop("qd0"), args.pop("controls"), args.pop("dt"), **args)
    for q, qd, u, error, message in [  # the shapes: tests/lagrange/model/test_chain.py
        (jnp.zeros(2, bool), jnp.zeros(2), jnp.zeros(1), TypeError, r"q must hold real numbers"),
        (jnp.zeros(2), jnp.zeros(2), jnp.zeros(1, complex), TypeError, r"u must hold real numbers"),
    ]:
        with pytest.raises(error, match=message):
            lg.step(chain, q, qd, u, 0.01)


def test_a_planar_chain_s_simulate_passes_through_eight_library_files_checking_once():
    """Issue 63's measure of the call path, by ``sys.setprofile``: a planar chain's ``simulate`` enters at most 8 of
    the library's files once the tree is prepared (today: rollout, interval, dynamics' dispatch, the planar model, the
    unrolled derivation, its unit-vector and scalar algebra, and the forces), and its first call checks the tree and
    its parameters exactly once (the second finds them prepared)."""
    import collections
    import os
    import sys

    root = os.path.dirname(lg.__file__)
    chain = lg.systems.acrobot(masses=(2.5 + np.pi * 1e-9, 2.5))  # parameters no other test prepares: a cold call
    q0, us = jnp.zeros(2), jnp.zeros((2, 1))

    def trace():
        files, calls = collections.Counter(), collections.Counter()

        def profile(frame, event, arg):
            if event == "call" and frame.f_code.co_filename.startswith(root):
                files[os.path.relpath(frame.f_code.co_filename, root)] += 1
                calls[frame.f_code.co_name] += 1

        sys.setprofile(profile)
        try:
            lg.simulate(chain, q0, q0, us, 0.01)
        finally:
            sys.setprofile(None)
        return files, calls

    _, cold = trace()
    assert cold["check_tree"] == 1 and cold["check_parameters"] == 1, cold
    files, warm = trace()
    assert warm["check_tree"] == warm["check_parameters"] == 0, warm
    assert len(files) <= 8, sorted(files)
    assert {"integrate/rollout.py", "planar/unrolled.py"} <= set(files)  # the trace saw the path
