"""Trajectories and gradients against Brax's generalized pipeline and finite differences of MuJoCo C.

The three engines run the same model: :func:`lagrange.interop.mjcf.to_mjcf` exports the chain, MuJoCo C
and ``brax.io.mjcf.loads`` load the string (Brax in float64: ``tests/conftest.py`` enables x64
before this module imports Brax), and ``lg.SemiImplicitEuler()`` takes the same steps as
MuJoCo's ``integrator="Euler"`` and Brax's semi-implicit Euler (joint damping implicit, exact
``M`` solve because the export sets ``matrix_inv_iterations=0``).

Errors are ``rel(a, b) = max|a - b| / max(1, max|b|)`` (``tests/helpers.py``). Tolerances:

- Trajectories, 500 steps: 1e-9 (the engines compute the same recurrence; round-off only).
- Automatic derivatives, ours against Brax's ``jax.jacrev``/``jax.grad``: 1e-10. Both
  differentiate the same float64 recurrence exactly, so they differ by round-off amplified by
  the sensitivity (|J| <= ~20 on these horizons); measured <= 2e-13.
- Ours against central differences of MuJoCo C: 1e-7. With step ``h = 1e-5`` (about
  eps_mach^(1/3), which balances the h^2 truncation error against the eps_mach/h round-off)
  the finite differences themselves are good to ~1e-9..1e-8 here.
- Horizons are 500 steps from hanging starts under random controls: sensitivities stay O(10),
  the flow is not chaotic there. The upright acrobot is: ``test_chaotic_upright_acrobot``
  measures where finite differences part from the (mutually agreeing) automatic derivatives
  and why.

Brax 0.14 gets a slide joint below a hinge wrong (``test_brax_bug_slide_joint_below_hinge``);
chains with one are checked against MuJoCo only.

Budget: Brax's pipeline compiles slowly (its ``jacrev`` of a 500-step rollout takes 10-30 s to compile per
model, its rollout alone 2-4 s, and no two models share a program), so each model is compiled once (trajectory
and derivatives from one jitted ``jacrev``) and Brax sees the fewest chains that still cover every structure the
library derives differently. Brax sees exactly these chains:

- gradients and trajectories (``GRADIENT_CASES``): ``cartpole`` (a prismatic base on the x axis under a hinge,
  undamped; 2 links, the unrolled derivation) and ``random3`` (a prismatic base on a slanted axis under four
  hinges, damping, armature, two actuators; 5 links, the recursive derivation);
- trajectories only (``TRAJECTORY_CASES``): ``random0`` (two hinges, damping and armature, the elbow actuated;
  unrolled) and ``random6`` (eight hinges, damping and armature: the deepest chain, recursive);
- the upright acrobot (``test_chaotic_upright_acrobot``), the pendulum carrying a slider
  (``test_brax_bug_slide_joint_below_hinge``) and ``random3`` (``test_export_loads_in_brax_in_float64``).

So Brax's derivatives cover revolute joints, a prismatic base (on the x axis and slanted), damping, armature and
both the unrolled (< 4 links) and the recursive (>= 4 links) derivations; its trajectories add an unrolled chain
with damping and armature and the deepest chain (no test here builds a branched tree). The Brax-safe chains that
Brax does not see keep their MuJoCo comparisons: the pendulum, acrobot, double cartpole and ``random0`` have their
trajectories and gradients checked against MuJoCo C (``test_gradients_match_mujoco_without_brax``), ``random4``
and ``random5`` their trajectories (``test_trajectory_matches_mujoco_without_brax``), and ``random1`` and
``random2`` are the seeded chains of ``test_against_mujoco.py`` (``test_brax_safe_chains_are_checked_against_mujoco``),
whose ``test_semi_implicit_euler_matches_mujoco_euler`` runs the same 500-step problem. MuJoCo sees every chain in
``test_against_mujoco.py``.
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.interop.mjcf import to_mjcf
from lagrange.planar.lower import lower as planar
from tests.helpers import (
    SYSTEMS,
    TRAJECTORY,
    has_slide_below_hinge,
    mujoco_model,
    mujoco_batch_rollout,
    seeded_chain,
    random_problem,
    rel,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # Brax's "not actively maintained" notice
    from brax.generalized import pipeline as brax_pipeline
    from brax.io import mjcf as brax_mjcf

# Brax 0.14 reads the deprecated MjData.ncon once per load; harmless here (no contacts)
pytestmark = pytest.mark.filterwarnings("ignore:Accessing `ncon` directly:DeprecationWarning")

AUTODIFF = 1e-10  # ours vs Brax: the same derivative of the same arithmetic
FINITE_DIFFERENCE = 1e-7  # ours/Brax vs central differences of MuJoCo C
FD_STEP = 1e-5
STEPS = 500


def brax_system(chain: Chain, dt: float):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return brax_mjcf.loads(to_mjcf(chain, timestep=dt))


def brax_trajectory(sys):
    """(q0, qd0, us) -> (q, qd) of shape (T + 1, n) through Brax's generalized pipeline."""

    def run(q0, qd0, us):
        def body(state, u):
            state = brax_pipeline.step(sys, state, u)
            return state, (state.q, state.qd)

        _, (q, qd) = jax.lax.scan(body, brax_pipeline.init(sys, q0, qd0), us)
        return jnp.concatenate([q0[None], q]), jnp.concatenate([qd0[None], qd])

    return run


def our_trajectory(chain: Chain, dt: float):
    def run(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, dt, lg.SemiImplicitEuler(), check=False)
        return tr.q, tr.qd

    return run


def loss(q, qd):
    """A scalar loss over the whole trajectory, like the tasks' costs."""
    return jnp.sum(q[1:] ** 2) + 0.01 * jnp.sum(qd[1:] ** 2)


def derivatives(trajectory):
    """One jitted function: the trajectory, and the Jacobian of (final q, final qd, loss) with
    respect to (q0, qd0, us), flattened to shape (2n + 1, 2n + T m); the last row is grad loss."""

    def outputs(x):
        q, qd = trajectory(*x)
        return jnp.concatenate([q[-1], qd[-1], loss(q, qd)[None]]), (q, qd)

    @jax.jit
    def run(q0, qd0, us):
        jac, traj = jax.jacrev(outputs, has_aux=True)((q0, qd0, us))
        rows = jac[0].shape[0]
        return jnp.concatenate([jac[0], jac[1], jac[2].reshape(rows, -1)], axis=1), traj

    return lambda q0, qd0, us: jax.tree.map(np.asarray, run(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us)))


def mujoco_finite_differences(chain: Chain, dt: float, q0, qd0, us, h=FD_STEP):
    """Central differences of (final q, final qd, loss) through MuJoCo C, same layout as ``derivatives``."""
    model, data = mujoco_model(chain, dt)
    n, (T, m) = chain.nv, us.shape
    cols = 2 * n + T * m
    x = np.concatenate([q0, qd0, us.ravel()])
    X = np.repeat(x[None], 2 * cols, axis=0)
    k = np.arange(cols)
    X[2 * k, k] += h
    X[2 * k + 1, k] -= h
    q, qd = mujoco_batch_rollout(model, data, X[:, :n], X[:, n : 2 * n], X[:, 2 * n :].reshape(-1, T, m))
    L = np.sum(q**2, axis=(1, 2)) + 0.01 * np.sum(qd**2, axis=(1, 2))
    out = np.concatenate([q[:, -1], qd[:, -1], L[:, None]], axis=1)
    return (out[0::2] - out[1::2]).T / (2 * h)


def _brax_safe(seed):
    chain = seeded_chain(seed, slide_below_hinge=False)
    assert not has_slide_below_hinge(chain)
    return chain


# The chains Brax sees (the module docstring says what each covers).
GRADIENT_CASES = [pytest.param(SYSTEMS["cartpole"][0](), SYSTEMS["cartpole"][1], id="cartpole"),
                  pytest.param(_brax_safe(3), 0.005, id="random3")]
TRAJECTORY_CASES = [pytest.param(_brax_safe(seed), 0.005, id=f"random{seed}") for seed in (0, 6)]
# Brax-safe chains checked against MuJoCo C only (Brax covers their structures on the chains above).
MUJOCO_GRADIENT_CASES = [pytest.param(SYSTEMS[name][0](), SYSTEMS[name][1], id=name)
                         for name in ("pendulum", "acrobot", "double_cartpole")]
MUJOCO_GRADIENT_CASES += [pytest.param(_brax_safe(0), 0.005, id="random0")]
MUJOCO_TRAJECTORY_CASES = [pytest.param(_brax_safe(seed), 0.005, id=f"random{seed}") for seed in (4, 5)]


def test_export_loads_in_brax_in_float64():
    chain = seeded_chain(3, slide_below_hinge=False)
    sys = brax_system(chain, 0.005)
    assert sys.matrix_inv_iterations == 0
    assert sys.opt.timestep.dtype == jnp.float64 and sys.link.inertia.mass.dtype == jnp.float64
    np.testing.assert_array_equal(sys.link.inertia.mass, np.asarray(chain.mass))
    np.testing.assert_array_equal(sys.dof.damping, np.asarray(planar(chain).damping))
    np.testing.assert_array_equal(sys.dof.armature, np.asarray(planar(chain).armature))
    np.testing.assert_array_equal(sys.actuator.gear, np.asarray(chain.gear))
    np.testing.assert_array_equal(sys.actuator.qd_id, chain.actuated)


@pytest.mark.parametrize("chain, dt", GRADIENT_CASES)
def test_trajectory_and_gradients_match_brax_and_mujoco(chain, dt):
    """500 steps: trajectories (1e-9), d(final state)/d(q0, qd0, controls) and grad of a loss
    against Brax's jacrev (1e-10) and central differences of MuJoCo C (1e-7)."""
    q0, qd0, us = random_problem(chain, 3, STEPS)
    J, (q, qd) = derivatives(our_trajectory(chain, dt))(q0, qd0, us)
    J_brax, (q_brax, qd_brax) = derivatives(brax_trajectory(brax_system(chain, dt)))(q0, qd0, us)
    model, data = mujoco_model(chain, dt)
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)

    assert rel(q[1:], q_mj[0]) <= TRAJECTORY and rel(qd[1:], qd_mj[0]) <= TRAJECTORY
    assert rel(q_brax[1:], q_mj[0]) <= TRAJECTORY and rel(qd_brax[1:], qd_mj[0]) <= TRAJECTORY

    J_fd = mujoco_finite_differences(chain, dt, q0, qd0, us)
    assert np.max(np.abs(J[:-1])) > 0.5  # the final state really depends on the inputs
    assert rel(J[:-1], J_brax[:-1]) <= AUTODIFF  # Jacobian of the final state
    assert rel(J[-1], J_brax[-1]) <= AUTODIFF  # gradient of the loss
    assert rel(J[:-1], J_fd[:-1]) <= FINITE_DIFFERENCE
    assert rel(J[-1], J_fd[-1]) <= FINITE_DIFFERENCE
    assert rel(J_brax, J_fd) <= FINITE_DIFFERENCE


@pytest.mark.parametrize("chain, dt", TRAJECTORY_CASES)
def test_trajectory_matches_brax(chain, dt):
    """500 steps of lg.SemiImplicitEuler() against Brax's generalized pipeline and MuJoCo C, 1e-9."""
    q0, qd0, us = random_problem(chain, 7, STEPS)
    run = jax.jit(brax_trajectory(brax_system(chain, dt)))
    q_brax, qd_brax = map(np.asarray, run(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us)))
    q, qd = map(np.asarray, jax.jit(our_trajectory(chain, dt))(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us)))
    model, data = mujoco_model(chain, dt)
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)
    assert rel(q, q_brax) <= TRAJECTORY and rel(qd, qd_brax) <= TRAJECTORY
    assert rel(q_brax[1:], q_mj[0]) <= TRAJECTORY and rel(qd_brax[1:], qd_mj[0]) <= TRAJECTORY


@pytest.mark.parametrize("chain, dt", MUJOCO_TRAJECTORY_CASES)
def test_trajectory_matches_mujoco_without_brax(chain, dt):
    """Brax-safe chains whose structures Brax covers on other chains (see the module docstring): 500 steps of
    lg.SemiImplicitEuler() against MuJoCo C, 1e-9, the problem ``test_trajectory_matches_brax`` runs."""
    assert not has_slide_below_hinge(chain)
    q0, qd0, us = random_problem(chain, 7, STEPS)
    q, qd = map(np.asarray, jax.jit(our_trajectory(chain, dt))(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us)))
    model, data = mujoco_model(chain, dt)
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)
    assert rel(q[1:], q_mj[0]) <= TRAJECTORY and rel(qd[1:], qd_mj[0]) <= TRAJECTORY


def test_brax_safe_chains_are_checked_against_mujoco():
    """The Brax-safe random1 and random2 are the seeded chains of ``test_against_mujoco.py`` (no slide joint below
    a hinge to replace), whose ``test_semi_implicit_euler_matches_mujoco_euler`` runs the same 500-step problem
    (``random_problem(chain, 7)`` at dt = 0.005 s): MuJoCo C still checks them without Brax."""
    for seed in (1, 2):
        assert to_mjcf(_brax_safe(seed), timestep=0.005) == to_mjcf(seeded_chain(seed), timestep=0.005)


def _gradients_match_mujoco(chain, dt):
    """Our 500-step trajectory against MuJoCo C (1e-9), and our d(final state)/d(q0, qd0, controls) and grad of
    the loss against central differences of MuJoCo C (1e-7)."""
    q0, qd0, us = random_problem(chain, 3, STEPS)
    J, (q, qd) = derivatives(our_trajectory(chain, dt))(q0, qd0, us)
    model, data = mujoco_model(chain, dt)
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)
    assert rel(q[1:], q_mj[0]) <= TRAJECTORY and rel(qd[1:], qd_mj[0]) <= TRAJECTORY
    J_fd = mujoco_finite_differences(chain, dt, q0, qd0, us)
    assert np.max(np.abs(J[:-1])) > 0.5
    assert rel(J[:-1], J_fd[:-1]) <= FINITE_DIFFERENCE
    assert rel(J[-1], J_fd[-1]) <= FINITE_DIFFERENCE


@pytest.mark.parametrize("chain, dt", MUJOCO_GRADIENT_CASES)
def test_gradients_match_mujoco_without_brax(chain, dt):
    """Brax-safe chains whose structures Brax differentiates on other chains (see the module docstring):
    trajectories and gradients against MuJoCo C, as ``test_trajectory_and_gradients_match_brax_and_mujoco``
    checks them."""
    assert not has_slide_below_hinge(chain)
    _gradients_match_mujoco(chain, dt)


@pytest.mark.parametrize("seed", [7, 3])
def test_gradients_match_mujoco_with_slide_joint_below_hinge(seed):
    """Chains Brax gets wrong (a slide joint below a hinge): gradients against MuJoCo C only."""
    chain, dt = seeded_chain(seed), 0.005
    assert has_slide_below_hinge(chain)
    _gradients_match_mujoco(chain, dt)


def test_brax_bug_slide_joint_below_hinge():
    """BRAX'S BUG (0.14.2), not ours: a prismatic link below a revolute one.

    Minimal reproduction: a pendulum carrying a slider. Brax's generalized pipeline parts from
    MuJoCo C by O(1) within one simulated second, while lagrange matches MuJoCo to 1e-9 (and
    Brax is exact when the slide joint sits at the base, see the cartpoles above). This test
    asserts that the disagreement exists; when it fails, Brax has fixed the bug and these chains
    can join ``GRADIENT_CASES``.
    """
    chain = Chain([Link("revolute", 1.0, 1.0, gear=1.0), Link("prismatic", 1.0, 0.5)])
    dt, steps = 0.01, 100
    q0, qd0 = np.array([0.3, 0.1]), np.zeros(2)
    us = np.zeros((steps, 1))
    model, data = mujoco_model(chain, dt)
    q_mj, _ = mujoco_batch_rollout(model, data, q0, qd0, us)
    q, _ = jax.jit(our_trajectory(chain, dt))(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us))
    q_brax, _ = jax.jit(brax_trajectory(brax_system(chain, dt)))(jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us))
    assert rel(q[1:], q_mj[0]) <= TRAJECTORY
    assert rel(q_brax[1:], q_mj[0]) > 0.1  # Brax is wrong by O(1)


def test_chaotic_upright_acrobot():
    """Where agreement is lost on a chaotic horizon, and why.

    The acrobot balanced upright (q = (pi, 0) + 0.01 noise, small random elbow torques, dt =
    0.01 s) is chaotic: the sensitivity |J_H| = max|d x_H / d x_0| grows from 1 to ~4e4 over 500
    steps (a least-squares fit of log|J_H| against t gives ~1.7/s, the largest Lyapunov
    exponent's finite-time estimate). Measured rel errors of d x_H / d x_0 against ours:

        H                  25      100     200     250     300     400     500
        |J_H|              18      94      4.4e2   3.3e3   5.3e3   6.6e3   3.9e4
        Brax jacfwd        6e-16   2e-15   1e-14   6e-14   3e-14   2e-13   1e-13
        FD, h = 1e-6       8e-11   1.1e-9  2.7e-9  6.9e-7  4.4e-7  2.5e-5  1.1e-5
        FD, h = 1e-5       8e-10   1.2e-7  2.9e-7  6.9e-5  4.4e-5  2.5e-3  1.6e-3
        FD, h = 1e-8       1.9e-8  5.6e-8  6.0e-8  6.1e-8  6.3e-8  5.7e-8  5.8e-8

    Our derivatives and Brax's agree to round-off at every horizon (both differentiate the same
    float64 recurrence; largest 9e-12). Central differences with h = 1e-6 agree to 1e-7 up to
    H = 200 (4.2e-8) and lose it from H ~ 245 on (>= 4e-6 for H >= 400): their truncation error
    h^2 |d^3 x_H / d x_0^3| / 6 grows faster than J itself (higher derivatives of a chaotic flow
    grow with higher powers of exp(lambda t)); the h^2 scaling proves it (h = 1e-5 is 100x
    worse than h = 1e-6 at every horizon). A step of 1e-8 trades truncation for round-off
    (eps_mach |x| / h, ~6e-8 relative, at most 1.3e-7) and agrees again at long horizons. The
    loss of agreement is the finite differences', not the gradient's.
    """
    chain, dt = lg.systems.acrobot(), 0.01
    rng = np.random.default_rng(0)
    q0 = np.array([np.pi, 0.0]) + 0.01 * rng.standard_normal(2)
    qd0 = 0.01 * rng.standard_normal(2)
    us = 0.1 * rng.standard_normal((STEPS, 1))

    def sensitivities(trajectory):
        def states(x0):
            q, qd = trajectory(x0[:2], x0[2:], jnp.asarray(us))
            return jnp.concatenate([q, qd], axis=1)

        return np.asarray(jax.jit(jax.jacfwd(states))(jnp.asarray(np.r_[q0, qd0])))  # (T+1, 4, 4)

    J = sensitivities(our_trajectory(chain, dt))
    J_brax = sensitivities(brax_trajectory(brax_system(chain, dt)))
    model, data = mujoco_model(chain, dt)

    def finite_differences(h):
        X = np.repeat(np.r_[q0, qd0][None], 8, axis=0)
        k = np.arange(4)
        X[2 * k, k] += h
        X[2 * k + 1, k] -= h
        q, qd = mujoco_batch_rollout(model, data, X[:, :2], X[:, 2:], us[None])
        s = np.concatenate([X[:, None], np.concatenate([q, qd], axis=2)], axis=1)  # (8, T+1, 4)
        return np.moveaxis((s[0::2] - s[1::2]) / (2 * h), 0, -1)  # (T+1, 4, 4)

    fd = {h: finite_differences(h) for h in (1e-5, 1e-6, 1e-8)}
    err = {h: np.array([rel(fd[h][H], J[H]) for H in range(STEPS + 1)]) for h in fd}
    err_brax = np.array([rel(J_brax[H], J[H]) for H in range(STEPS + 1)])
    size = np.abs(J).max(axis=(1, 2))

    # chaos: the sensitivity grows by four orders of magnitude
    assert size[:26].max() < 100 and size[-1] > 1e4
    t = dt * np.arange(1, STEPS + 1)
    assert np.polyfit(t, np.log(size[1:]), 1)[0] > 1.0  # finite-time Lyapunov exponent [1/s]
    # Brax and ours agree to round-off all along
    assert err_brax.max() <= AUTODIFF
    # finite differences (h = 1e-6) agree on the non-chaotic part of the horizon...
    assert err[1e-6][:201].max() <= FINITE_DIFFERENCE
    # ...and lose agreement beyond it, by orders of magnitude more than Brax and ours differ
    assert err[1e-6][400:].min() > FINITE_DIFFERENCE
    assert err[1e-6][400:].min() > 1e4 * err_brax[400:].max()
    # why: truncation error, which scales as h^2 (10x the step, 100x the error)
    assert 30 < np.median(err[1e-5][100:] / err[1e-6][100:]) < 300
    # a step of 1e-8 trades truncation for round-off and agrees far better at long horizons
    assert err[1e-8].max() <= 1e-6
    assert np.min(err[1e-6][400:] / err[1e-8][400:]) > 10
