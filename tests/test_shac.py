"""SHAC (optim/shac/, its networks in policies/actor_critic.py) and the SHAC authors' cartpole (lagrange/shac_cartpole.py).

Each piece is checked against an independent computation: TD(lambda) targets against the explicit
lambda-weighted sum of n-step returns, the window loss against its definition computed by a plain
Python loop, the gradient cuts against a decomposition of the window at a reset, the target critic
against the soft-update formula, and the whole algorithm by the return it reaches.
"""

from __future__ import annotations

import dataclasses
import json
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.shac_cartpole import POLE_INERTIA, shac_cartpole
from lagrange.tasks import TaskState, balanced, chain_swingup, make_task, upright_error
from optim import shac

# ---------------------------------------------------------------------------------------------
# the authors' cartpole


def test_shac_cartpole_physics_and_readings():
    task = shac_cartpole()
    c = task.chain
    np.testing.assert_allclose(np.asarray(c.mass), [50.0, 2.5])
    np.testing.assert_allclose(np.asarray(c.gear), [1000.0])
    np.testing.assert_allclose(POLE_INERTIA, 2.5 * (1 + 0.05**2) / 12)
    assert (task.dt, task.horizon, task.observation_size, task.action_size) == (1 / 60, 240, 5, 1)
    # Upright pole at rest, cart at 0: reward 0 (the maximum); observation (x, dx, sin th, cos th, dth).
    up = TaskState(jnp.array([0.0, jnp.pi]), jnp.zeros(2))
    assert float(task.reward(up, jnp.zeros(1), up)) == 0.0
    # "balanced" reads the pole after the cart (examples/shac_cartpole.py evaluates with it)
    traj = jnp.stack([up.q, up.q.at[1].add(0.1), up.q.at[1].add(0.3)])
    assert bool(balanced(task, traj[:2])) and not bool(balanced(task, traj))
    np.testing.assert_allclose(upright_error(task, traj), [0.0, 0.1, 0.3], atol=1e-6)
    np.testing.assert_allclose(task.observe(up), [0, 0, 0, 1, 0], atol=1e-15)
    # The authors' weights, by hand: th = q - pi wrapped.
    s = TaskState(jnp.array([0.3, 0.5]), jnp.array([-0.7, 2.0]))
    th = 0.5 - math.pi
    want = -(th**2 + 0.1 * 2.0**2 + 0.05 * 0.3**2 + 0.1 * 0.7**2)
    np.testing.assert_allclose(float(task.reward(s, jnp.zeros(1), s)), want, rtol=1e-14)
    np.testing.assert_allclose(task.observe(s), [0.3, -0.7, math.sin(th), math.cos(th), 2.0], rtol=1e-14)
    # Reset: hanging down with U(-pi/2, pi/2) on x, q and U(-0.25, 0.25) on velocities.
    states = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 4000))
    q, qd = np.asarray(states.q), np.asarray(states.qd)
    assert np.abs(q).max() <= math.pi / 2 and np.abs(q).max() > 0.99 * math.pi / 2
    assert np.abs(qd).max() <= 0.25 and np.abs(qd).max() > 0.99 * 0.25
    # Dynamics, closed form: from rest hanging down, a cart force F gives
    # [[M + m, m c], [m c, I + m c^2]] (xdd, qdd) = (F, 0) with c = 0.5 m (sign of qdd aside).
    M, m, cc, inertia, F = 50.0, 2.5, 0.5, POLE_INERTIA, 1000.0
    det = (M + m) * (inertia + m * cc**2) - (m * cc) ** 2
    rest = TaskState(jnp.zeros(2), jnp.zeros(2))
    qdd = lg.forward_dynamics(c, rest.q, rest.qd, jnp.array([1.0]))
    np.testing.assert_allclose(float(qdd[0]), F * (inertia + m * cc**2) / det, rtol=1e-13)
    np.testing.assert_allclose(abs(float(qdd[1])), F * m * cc / det, rtol=1e-13)
    # Actions are clipped to [-1, 1] before the gear.
    a1, a2 = task.step(rest, jnp.array([3.0])), task.step(rest, jnp.array([1.0]))
    np.testing.assert_array_equal(np.asarray(a1.q), np.asarray(a2.q))


def test_shac_cartpole_rejects_bad_fields():
    with pytest.raises(ValueError, match="horizon"):
        shac_cartpole(horizon=0)
    with pytest.raises(ValueError, match="noise_q"):
        shac_cartpole(noise_q=-1.0)


# ---------------------------------------------------------------------------------------------
# pieces


def _n_step_lambda_return(r, v, done, gamma, lam, t):
    """(1 - lam) sum_{n<k} lam^(n-1) G^(n) + lam^(k-1) G^(k), k = steps to the next end (inclusive)."""
    T = len(r)
    end = next(j for j in range(t, T) if done[j] or j == T - 1)
    k = end - t + 1

    def G(n):  # n-step return from t: rewards t..t+n-1, bootstrap with V of the state step t+n-1 lands in
        return sum(gamma**i * r[t + i] for i in range(n)) + gamma**n * v[t + n - 1]

    return (1 - lam) * sum(lam ** (n - 1) * G(n) for n in range(1, k)) + lam ** (k - 1) * G(k)


def test_td_lambda_targets_match_the_lambda_weighted_n_step_returns():
    rng = np.random.default_rng(0)
    T, N, gamma, lam = 9, 3, 0.99, 0.95
    r = rng.normal(size=(T, N))
    v = rng.normal(size=(T, N))
    done = np.zeros((T, N), bool)
    done[3, 0] = True  # an episode ends inside the window for env 0
    done[0, 2] = done[6, 2] = True
    got = np.asarray(shac.td_lambda_targets(jnp.asarray(r), jnp.asarray(v), jnp.asarray(done), gamma, lam))
    want = np.array([[_n_step_lambda_return(r[:, j], v[:, j], done[:, j], gamma, lam, t) for j in range(N)]
                     for t in range(T)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    # lam = 0: one-step targets; lam = 1: Monte-Carlo returns bootstrapped at the window end.
    np.testing.assert_allclose(shac.td_lambda_targets(r, v, done, gamma, 0.0), r + gamma * v, rtol=1e-13)


@pytest.fixture(scope="module")
def tiny():
    """A tiny SHAC trainer on the pendulum (one compilation shared by the tests that use it)."""
    cfg = shac.SHACConfig(task="custom", num_envs=4, short_horizon=4, epochs=10, critic_iterations=2,
                          critic_minibatches=2, actor_units=(8,), critic_units=(8,), target_alpha=0.3)
    return cfg, shac.make_trainer(cfg, _pendulum())


def test_soft_update_formula_and_trainer_uses_it(tiny):
    a = {"w": jnp.array([1.0, 2.0]), "b": jnp.array(3.0)}
    b = {"w": jnp.array([5.0, -2.0]), "b": jnp.array(-1.0)}
    out = shac.soft_update(a, b, 0.2)
    np.testing.assert_allclose(out["w"], [0.2 * 1 + 0.8 * 5, 0.2 * 2 - 0.8 * 2], rtol=1e-15)
    np.testing.assert_allclose(out["b"], 0.2 * 3 - 0.8 * 1, rtol=1e-15)
    # In one epoch of the trainer: new target = alpha * old target + (1 - alpha) * new critic.
    cfg, tr = tiny
    assert cfg.target_alpha == 0.3
    s0 = tr.init(jax.random.PRNGKey(0))
    s0 = s0._replace(target_critic=jax.tree_util.tree_map(lambda x: x + 0.5, s0.target_critic))
    s1, _ = tr.update(s0)
    assert not np.allclose(np.asarray(s1.critic.net.out.weight), np.asarray(s0.critic.net.out.weight))
    for t1, t0, c1 in zip(jax.tree_util.tree_leaves(s1.target_critic), jax.tree_util.tree_leaves(s0.target_critic),
                          jax.tree_util.tree_leaves(s1.critic)):
        np.testing.assert_allclose(t1, 0.3 * t0 + 0.7 * c1, rtol=1e-13, atol=1e-15)


def test_state_round_trips_through_a_checkpoint(tiny, tmp_path):
    """A SHAC state saved with optim.checkpoint and loaded back continues exactly like the original."""
    from optim import checkpoint

    cfg, tr = tiny
    config = json.loads(json.dumps(dataclasses.asdict(cfg)))
    s1, _ = tr.update(tr.init(jax.random.PRNGKey(0)))
    path = tmp_path / "shac.eqx"
    checkpoint.save(path, s1, config=config, iteration=1)
    loaded, head = checkpoint.load(path, tr.init(jax.random.PRNGKey(1)), config=config)
    assert head["iteration"] == 1 and int(loaded.iteration) == 1
    a, _ = tr.update(s1)
    b, _ = tr.update(loaded)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_learning_rates_decay_linearly_to_lr_end():
    cfg = shac.SHACConfig(epochs=500)
    a0, c0 = cfg.learning_rates(0)
    a1, c1 = cfg.learning_rates(250)
    a2, c2 = cfg.learning_rates(500)
    np.testing.assert_allclose([a0, c0], [1e-2, 1e-3], rtol=1e-6)
    np.testing.assert_allclose([a1, c1], [(1e-2 + 1e-5) / 2, (1e-3 + 1e-5) / 2], rtol=1e-6)
    np.testing.assert_allclose([a2, c2], [1e-5, 1e-5], rtol=1e-6)


def test_config_errors_name_the_field():
    for kwargs, field in (({"gamma": 1.5}, "gamma"), ({"num_envs": 0}, "num_envs"), ({"task": "nope"}, "task"),
                          ({"actor_units": (64, 0)}, "actor_units"), ({"adam_b1": 1.0}, "adam_b1"),
                          ({"lam": -0.1}, "lam"), ({"critic_minibatches": 10**6}, "critic_minibatches"),
                          ({"task": "acrobot", "bodies": "capsules"}, r"bodies must be one of \['rods', 'brax_v1'\]"),
                          ({"bodies": "brax_v1"}, "SHACConfig.bodies='brax_v1' is for the paper tasks")):
        with pytest.raises(ValueError, match=field):
            shac.SHACConfig(**kwargs)


def test_bodies_field_builds_the_brax_v1_task():
    """``SHACConfig.bodies`` reaches the trainer's task, as ``CEAPGConfig.bodies`` does (benchmarks/algorithms.py
    --bodies trains SHAC on the authors' Brax v1 acrobot through it)."""
    cfg = dict(num_envs=4, short_horizon=4, epochs=2, critic_iterations=1, critic_minibatches=1)
    rods = shac.make_trainer(shac.SHACConfig(task="acrobot", **cfg)).task
    brax = shac.make_trainer(shac.SHACConfig(task="acrobot", bodies="brax_v1", **cfg)).task
    for task, bodies in ((rods, "rods"), (brax, "brax_v1")):
        want = make_task("acrobot", bodies).chain
        for field in ("mass", "length", "com", "inertia"):
            np.testing.assert_array_equal(getattr(task.chain, field), getattr(want, field))
    assert not np.allclose(brax.chain.inertia, rods.chain.inertia)


# ---------------------------------------------------------------------------------------------
# the window loss and its gradient cuts

_H = 6  # window length of the loss tests


def _pendulum(horizon=100, noise=0.01):
    """A small task: pendulum swing-up (1 kg, 1 m, torque 5 a N m; gravity's largest torque is 4.9 N m)
    with the acrobot's reward 10 - th^2 - 0.01 dth^2 per step, dt 0.05 s."""
    return chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=horizon, noise=noise)


def _setup(noise=0.0):
    task = _pendulum(horizon=10, noise=noise)
    k = jax.random.split(jax.random.PRNGKey(3), 3)
    # log_std = -1000: exp underflows to exactly 0, so the actor's actions are deterministic.
    actor = shac.Actor(2, 1, (8,), init_log_std=-1000.0, key=k[0])
    critic = shac.Critic(2, (8,), key=k[1])
    env = jax.vmap(task.reset)(jax.random.split(k[2], 3))
    env = TaskState(env.q + jnp.array([2.5]), env.qd + jnp.array([-1.0]))
    return task, actor, critic, env


def _loss(actor, critic, task, env, progress, h, key=jax.random.PRNGKey(7)):
    return shac.actor_loss(actor, critic, None, task, env, progress, jnp.zeros(progress.shape), key,
                           short_horizon=h, horizon=task.horizon, gamma=0.99)


def test_window_loss_matches_its_definition():
    """No episode ends: -(sum_t gamma^t r_t + gamma^h V(s_h)) averaged over envs, divided by h."""
    task, actor, critic, env = _setup()
    loss, win = jax.jit(lambda e: _loss(actor, critic, task, e, jnp.zeros(3, jnp.int32), _H))(env)

    @jax.jit
    def reference(env):
        want = 0.0
        for j in range(3):
            s = TaskState(env.q[j], env.qd[j])
            ret = 0.0
            for t in range(_H):
                a = actor.deterministic(task.observe(s))
                s2 = task.step(s, a)
                ret += 0.99**t * task.reward(s, a, s2)
                s = s2
            want += -(ret + 0.99**_H * critic(task.observe(s)))
        return want / (_H * 3)

    np.testing.assert_allclose(float(loss), float(reference(env)), rtol=1e-12)
    assert not bool(win.dones.any())


def test_gradient_is_cut_at_the_window_start():
    """The loss does not depend, through the gradient, on how the window's start state was reached."""
    task, actor, critic, env = _setup()
    g = jax.jit(jax.grad(lambda e: _loss(actor, critic, task, e, jnp.zeros(3, jnp.int32), _H)[0]))(env)
    for leaf in jax.tree_util.tree_leaves(g):
        assert np.all(np.asarray(leaf) == 0.0)  # exactly zero
    # ... while the same loss without the cut does depend on it (the test can fail).
    def uncut(e):
        s, ret = TaskState(e.q[0], e.qd[0]), 0.0
        for t in range(_H):
            a = actor.deterministic(task.observe(s))
            s2 = task.step(s, a)
            ret = ret + 0.99**t * task.reward(s, a, s2)
            s = s2
        return -ret
    assert float(jnp.abs(jax.jit(jax.grad(uncut))(env).q).max()) > 1e-3


def test_gradient_through_a_reset_is_zero():
    """An episode that ends at step k of the window splits it into two independent windows: the loss and
    its actor gradient equal those of the window before the reset plus the window after it (the reset
    state being the task's deterministic reset, noise 0), so no gradient crosses the reset."""
    task, actor, critic, env = _setup(noise=0.0)
    k = 2
    progress = jnp.full(3, task.horizon - k, jnp.int32)  # every episode ends after k steps

    def full(act):
        return _loss(act, critic, task, env, progress, _H)[0] * (_H * 3)

    def before(act):  # the k steps up to the episode end, bootstrapped with V of the last state
        return _loss(act, critic, task, env, progress, k)[0] * (k * 3)

    def after(act):  # the h - k steps from the reset state
        fresh = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 3))
        return _loss(act, critic, task, fresh, jnp.zeros(3, jnp.int32), _H - k)[0] * ((_H - k) * 3)

    @eqx.filter_jit
    def everything(act):  # one compilation for the three losses, their gradients and the window
        return ([eqx.filter_value_and_grad(f)(act) for f in (full, before, after)],
                _loss(act, critic, task, env, progress, _H)[1])

    ((v_full, g_full), (v_before, g_before), (v_after, g_after)), win = everything(actor)
    assert np.asarray(win.dones)[k - 1].all() and not np.asarray(win.dones)[k:].any()
    np.testing.assert_allclose(float(v_full), float(v_before) + float(v_after), rtol=1e-12)
    g_sum = jax.tree_util.tree_map(lambda a, b: a + b, g_before, g_after)
    for a, b in zip(jax.tree_util.tree_leaves(g_full), jax.tree_util.tree_leaves(g_sum)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
    assert max(float(jnp.abs(x).max()) for x in jax.tree_util.tree_leaves(g_full)) > 1e-6  # not trivially zero


# ---------------------------------------------------------------------------------------------
# the algorithm


def test_shac_improves_a_pendulum_swingup():
    """make_train (the whole run under one jit): 100 epochs x 32 envs x 16-step windows (5e4 simulated
    steps) lift the deterministic return over 16 random starts of the pendulum swing-up (max 1000) from
    the untrained policy's (about 50 at this seed) above 600. (The authors' cartpole with their full
    config: examples/shac_cartpole.py.)"""
    cfg = shac.SHACConfig(task="custom", num_envs=32, epochs=100, short_horizon=16)
    task = _pendulum()
    trainer = shac.make_trainer(cfg, task)
    key, eval_key = jax.random.PRNGKey(0), jax.random.PRNGKey(1)
    before, _ = trainer.evaluate(trainer.init(key), eval_key, 16)
    state, metrics = jax.jit(shac.make_train(cfg, task))(key)
    after, _ = trainer.evaluate(state, eval_key, 16)
    assert int(state.iteration) == 100
    assert float(jnp.sum(metrics["env_steps"])) == 100 * 32 * 16
    assert int(jnp.sum(metrics["nonfinite"])) == 0
    assert float(jnp.mean(before)) < 200
    assert float(jnp.mean(after)) > 600, float(jnp.mean(after))
