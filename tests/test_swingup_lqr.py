"""benchmarks/swingup_lqr.py: open-loop swing-up (CEM) caught by a saturated LQR, refined by Adam."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks import swingup_lqr as sl
from benchmarks.upright_basin import linearise, lqr_gain
from lagrange import tasks


def gain(task, r=1.0):
    A, B = linearise(task)
    return lqr_gain(A, B, r)


def test_the_lqr_phase_holds_the_double_cartpole_from_every_noisy_upright_start():
    task = dataclasses.replace(tasks.double_cartpole(), upright=1.0)
    episode = sl.make_controller(task, gain(task), T=0)  # LQR from the first step, no offsets
    starts = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 16))
    ret, states, a, _ = jax.vmap(lambda s: episode(jnp.zeros(task.horizon), s))(starts)
    q = states.q
    assert bool(jnp.all(tasks.balanced(task, q)))
    # 10 per step at most; the +-0.01 start noise costs a little at the beginning only
    assert float(jnp.min(ret)) > 10 * task.horizon - 1.0 and float(jnp.max(ret)) <= 10 * task.horizon
    assert float(jnp.max(jnp.abs(q[:, -1, 0]))) < 1e-3  # the cart is brought back to the origin


def test_the_reported_actions_are_the_ones_applied():
    """Replayed open loop over a short float64 episode they give the same states (over 500 steps round-off grows)."""
    task = dataclasses.replace(tasks.acrobot(), horizon=60)
    T = 25
    episode = sl.make_controller(task, gain(task), T)
    z = 0.5 * jax.random.normal(jax.random.PRNGKey(1), (task.horizon,))
    s0 = task.reset(jax.random.PRNGKey(2))
    ret, states, actions, rewards = episode(z, s0)
    q = states.q
    np.testing.assert_allclose(np.asarray(actions[:T]), np.tanh(np.asarray(z[:T])), rtol=1e-12)

    def body(s, a):
        s2 = task.step(s, a[None])
        return s2, (task.reward(s, a[None], s2), s2.q, s2.qd)

    _, (r, q2, qd2) = jax.lax.scan(body, s0, actions)
    np.testing.assert_allclose(np.asarray(q[1:]), np.asarray(q2), atol=1e-12)
    np.testing.assert_allclose(np.asarray(states.qd[1:]), np.asarray(qd2), atol=1e-12)
    np.testing.assert_array_equal(np.asarray(states.q[0]), np.asarray(s0.q))
    np.testing.assert_allclose(float(ret), float(r.sum()), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(rewards), np.asarray(r), atol=1e-12)


def test_the_float64_rerun_keeps_the_tasks_bodies():
    """``rerun_float64`` rebuilds the task in float64 on the bodies the task records (``Task.bodies``), so a Brax v1
    controller is re-checked on the Brax v1 chain: its return equals the same episode run directly in float64."""
    z = 0.5 * jax.random.normal(jax.random.PRNGKey(3), (500,))
    got = {}
    for bodies in tasks.BODIES:
        task = tasks.make_task("acrobot", bodies)
        K = gain(task)
        got[bodies], _ = sl.rerun_float64(task, K, 40, z)
        with jax.enable_x64(True):
            task64 = tasks.make_task("acrobot", bodies)
            want, _, _, _ = jax.jit(sl.make_controller(task64, K, 40))(jnp.asarray(z, jnp.float64), sl.hanging(task64))
        assert got[bodies] == float(want)
    assert got["rods"] != got["brax_v1"]


def test_knots_to_offsets():
    z = sl.knots_to_offsets(jnp.array([1.0, -1.0, 3.0]), 5, 8)
    np.testing.assert_allclose(np.asarray(z), [1.0, 0.0, -1.0, 1.0, 3.0, 0.0, 0.0, 0.0])


def test_cem_finds_the_maximum_of_a_quadratic():
    target = jnp.array([1.5, -0.5, 2.0, 0.0])
    c, best = sl.cem(lambda c: -jnp.sum((c - target) ** 2), 4, jax.random.PRNGKey(0), population=256, elites=16,
                     iterations=40, init_std=3.0, dtype=jnp.float64)
    np.testing.assert_allclose(np.asarray(c), np.asarray(target), atol=0.05)
    assert -0.01 < best <= 0.0


def test_main_writes_a_replayable_result(tmp_path):
    out = tmp_path / "s.json"
    sl.main(["--task", "cartpole", "--times", "40", "--seeds", "0", "--population", "256", "--elites", "16",
             "--iterations", "15", "--refine-steps", "50", "--out", str(out), "--plot", str(tmp_path / "best.png")])
    assert (tmp_path / "best.png").stat().st_size > 10_000  # the best controller's episode, drawn
    d = json.loads(out.read_text())
    row = d["rows"][0]
    assert row["T"] == 40 and row["return"] >= row["cem_return"] - 1e-6 * abs(row["cem_return"])
    # the tests run in float64, so the float64 re-run is the same episode
    assert row["return_float64"] == pytest.approx(row["return"], rel=1e-9) and row["balanced_float64"] == row["balanced"]
    assert d["best"] is not None, "the cartpole's swing-up and LQR catch should be found even by this small search"
    best = d["best"]
    task = tasks.cartpole()
    episode = sl.make_controller(task, np.asarray(d["lqr_gain"]), best["T"])
    s0 = tasks.TaskState(jnp.zeros(2), jnp.zeros(2))
    ret, states, actions, _ = episode(jnp.asarray(best["offsets"]), s0)
    q = states.q
    assert float(ret) == pytest.approx(best["return"], rel=1e-9) and bool(tasks.balanced(task, q))
    # a balanced episode arrives; the penalties before and after arrival add up to 10 per step minus the return
    assert best["arrival_step"] is not None and best["arrival_step"] <= task.horizon * 0.8
    assert best["penalty_before_arrival"] + best["penalty_after_arrival"] == pytest.approx(
        10 * task.horizon - best["return"], rel=1e-9, abs=1e-6)
    np.testing.assert_allclose(np.asarray(actions), best["actions"], atol=1e-12)
    # --replot draws the saved best controller again without searching; a file without one for the task is refused
    sl.main(["--task", "cartpole", "--out", str(out), "--replot", "--plot", str(tmp_path / "again.png")])
    assert (tmp_path / "again.png").stat().st_size > 10_000
    with pytest.raises(SystemExit, match="--task acrobot"):
        sl.main(["--task", "acrobot", "--out", str(out), "--replot", "--plot", str(tmp_path / "no.png")])
    with pytest.raises(SystemExit, match="--plot"):
        sl.main(["--task", "cartpole", "--out", str(out), "--replot"])
    with pytest.raises(SystemExit, match="--bodies brax_v1"):  # a rods result is not the Brax v1 bodies' controller
        sl.main(["--task", "cartpole", "--bodies", "brax_v1", "--out", str(out), "--replot", "--plot",
                 str(tmp_path / "no.png")])
    assert sl.results_path("acrobot", bodies="brax_v1").endswith("swingup_lqr_acrobot_brax_v1.json")


@pytest.mark.parametrize("argv, field", [(["--elites", "5000"], "--elites"), (["--times", "600"], "--times"),
                                         (["--lr", "-1"], "--lr"), (["--knots", "1"], "--knots")])
def test_bad_arguments_name_the_flag(argv, field):
    with pytest.raises(SystemExit, match=field):
        sl.main(["--task", "cartpole", *argv])
