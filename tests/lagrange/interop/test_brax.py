"""The Brax adapter (lagrange/interop/brax.py): it reproduces the task exactly, ends episodes at the horizon, runs
in Brax's own machinery (its training wrappers and PPO trainer), and ``brax_training_compat`` restores ``jax``'s
namespace on exit. (That importing the adapters changes no other module is in tests/lagrange/test_imports.py.)"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange.tasks import Cartpole, DoubleCartpole


def _task_rollout(task, key, actions):
    """The task's own rollout: observations (T+1, obs), rewards (T,)."""
    s = task.reset(key)
    obs, rew = [task.observe(s)], []
    for a in actions:
        s2 = task.step(s, a)
        rew.append(task.reward(s, a, s2))
        obs.append(task.observe(s2))
        s = s2
    return jnp.stack(obs), jnp.stack(rew)


def test_brax_env_carries_the_last_action_of_a_task_that_observes_it():
    """The Ant observes the last action (``TaskState.action``): through the adapter its observations and rewards are
    the task's own, step for step (the adapter once dropped the action and the Ant's first step raised). One substep
    per control step: the adapter is what is tested, and the program compiles in a fraction of the time."""
    from lagrange.interop.brax import BraxEnv
    from lagrange.tasks import Ant

    task = dataclasses.replace(Ant.diffrl(), substeps=1)
    env = BraxEnv(task)
    key = jax.random.PRNGKey(2)
    actions = jax.random.uniform(jax.random.PRNGKey(3), (3, task.action_size), minval=-1.0, maxval=1.0)

    @jax.jit
    def both(key, actions):
        def ours(s, a):
            s2 = task.step(s, a)
            return s2, (task.observe(s2), task.reward(s, a, s2))

        def brax(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.reward, s.pipeline_state.action)

        return jax.lax.scan(ours, task.reset(key), actions)[1], jax.lax.scan(brax, env.reset(key), actions)[1]

    (want_obs, want_rew), (obs, rew, last) = both(key, actions)
    np.testing.assert_array_equal(np.asarray(last), np.asarray(actions))  # in [-1, 1]: nothing clipped
    np.testing.assert_allclose(np.asarray(obs), np.asarray(want_obs), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(rew), np.asarray(want_rew), rtol=1e-12, atol=1e-12)
    assert jax.eval_shape(env.reset, key).pipeline_state.action.shape == (task.action_size,)
    assert jax.eval_shape(BraxEnv(Cartpole.rods()).reset, key).pipeline_state.action is None  # it observes none


def test_brax_training_compat_installs_the_removed_jax_names_for_its_duration_only(monkeypatch):
    """Brax 0.14.2 calls ``jax.device_put_replicated`` (``brax.training.pmap.bcast_local_devices``, and its
    trainers directly), which JAX 0.10 removed. Inside the context the call works with JAX's own implementation;
    on exit, also by an exception and from nested contexts, ``jax``'s namespace is what it was; a name ``jax``
    already has is left alone."""
    from brax.training import pmap
    from jax._src import api

    from lagrange.interop.brax import brax_training_compat

    names = ("device_put_replicated", "device_put_sharded")
    before = sorted(dir(jax))
    had = {n: hasattr(jax, n) for n in names}
    assert not any(had.values())  # JAX 0.10.2, this project's pin
    x = jnp.arange(3.0)
    with pytest.raises(AttributeError):
        pmap.bcast_local_devices(x)
    with brax_training_compat():
        assert all(getattr(jax, n) is getattr(api, n) for n in names)
        with brax_training_compat():  # nested: the inner context installs nothing and removes nothing
            pass
        assert all(getattr(jax, n) is getattr(api, n) for n in names)
        np.testing.assert_array_equal(np.asarray(pmap.bcast_local_devices(x)), np.asarray(x)[None])
    assert sorted(dir(jax)) == before and {n: hasattr(jax, n) for n in names} == had

    with pytest.raises(RuntimeError, match="inside"):
        with brax_training_compat():
            raise RuntimeError("inside")
    assert sorted(dir(jax)) == before and {n: hasattr(jax, n) for n in names} == had

    mine = object()
    monkeypatch.setattr(jax, "device_put_sharded", mine, raising=False)
    with brax_training_compat():
        assert jax.device_put_sharded is mine and jax.device_put_replicated is api.device_put_replicated
    assert jax.device_put_sharded is mine and not hasattr(jax, "device_put_replicated")


def test_brax_env_reproduces_the_task_and_ends_at_the_horizon():
    from brax.envs.wrappers import training

    from lagrange.interop.brax import BraxEnv

    task = DoubleCartpole.rods(horizon=7)
    env = BraxEnv(task)
    assert (env.observation_size, env.action_size) == (8, 1)
    key = jax.random.PRNGKey(4)
    actions = jax.random.uniform(jax.random.PRNGKey(5), (7, 1), minval=-1.5, maxval=1.5)
    want_obs, want_rew = jax.jit(_task_rollout)(task, key, actions)

    @jax.jit
    def brax_rollout(key, actions):
        state = env.reset(key)

        def body(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.reward, s.done)

        return state.obs, jax.lax.scan(body, state, actions)[1]

    obs0, (obs, rew, done) = brax_rollout(key, actions)
    # The same float64 arithmetic compiled as a scan and as an unrolled loop: equal to round-off.
    np.testing.assert_array_equal(np.asarray(obs0), np.asarray(want_obs[0]))
    np.testing.assert_allclose(np.asarray(obs), np.asarray(want_obs[1:]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(rew), np.asarray(want_rew), rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(done), [0, 0, 0, 0, 0, 0, 1])

    # Under Brax's own training wrappers (vmap, episode, auto-reset), the step after the horizon starts a
    # new episode from the first state: the counter lives in pipeline_state and is reset with it.
    wrapped = training.wrap(env, episode_length=7)
    keys = jax.random.split(key, 2)
    s = jax.jit(wrapped.reset)(keys)
    first = s.obs
    step = jax.jit(wrapped.step)
    for t in range(7):
        s = step(s, actions[t][None].repeat(2, 0))
    np.testing.assert_array_equal(np.asarray(s.done), [1, 1])
    np.testing.assert_array_equal(np.asarray(s.obs), np.asarray(first))  # auto-reset to the first state
    np.testing.assert_array_equal(np.asarray(s.pipeline_state.t), [0, 0])


def test_brax_ppo_runs_one_iteration_on_a_task():
    """brax.training.agents.ppo.train, unchanged, for one training iteration on the cartpole (horizon 50):
    it evaluates before and after, every evaluation episode lasts exactly the horizon, and the policy it
    returns acts in [-1, 1]."""
    from brax.training.agents.ppo import train as ppo

    from lagrange.interop.brax import BraxEnv, brax_training_compat

    task = Cartpole.rods(horizon=50)
    log = []
    with brax_training_compat():
        make_policy, params, _ = ppo.train(
            environment=BraxEnv(task), num_timesteps=1, episode_length=50, num_envs=4, batch_size=4,
            num_minibatches=1, unroll_length=5, num_updates_per_batch=1, num_evals=2, num_eval_envs=2, seed=0,
            progress_fn=lambda step, metrics: log.append((step, {k: float(v) for k, v in metrics.items()})))
    assert [step for step, _ in log] == [0, 20]  # one iteration: 4 envs x 5 unroll steps
    for _, m in log:
        assert np.isfinite(m["eval/episode_reward"])
        assert -50 * np.pi**2 <= m["eval/episode_reward"] <= 0.0  # reward -th^2 per step, |th| <= pi
        assert m["eval/avg_episode_length"] == 50.0
    policy = make_policy(params, deterministic=True)
    obs = jnp.zeros(task.observation_size, jnp.float32)
    action, _ = policy(obs, jax.random.PRNGKey(0))
    assert action.shape == (1,) and bool(jnp.all(jnp.abs(action) <= 1.0))


def test_brax_env_refuses_a_batch_where_one_is_expected():
    """A (1, 1) action once turned the state into a batch and returned another reward; the adapter takes one action
    of shape (action_size,) and one key, and names the shape it got (Brax's VmapWrapper vmaps over batches)."""
    from brax.envs.wrappers import training

    from lagrange.interop.brax import BraxEnv

    with pytest.raises(TypeError, match=r"BraxEnv task must be a task of lagrange\.tasks "
                                        r"\(an AbstractTask\), got None"):
        BraxEnv(None)
    env = BraxEnv(Cartpole.rods(horizon=5))
    state = env.reset(jax.random.PRNGKey(0))
    for action, shape in ((jnp.zeros((1, 1)), r"\(1, 1\)"), (jnp.zeros(()), r"\(\)"), (jnp.zeros(2), r"\(2,\)")):
        with pytest.raises(ValueError, match=rf"BraxEnv\.step: action must have shape \(action_size,\) = \(1,\), got "
                                             rf"{shape}; jax\.vmap the step"):
            env.step(state, action)
    with pytest.raises(TypeError, match=r"BraxEnv\.step: action must hold real numbers in \[-1, 1\], got dtype bool"):
        env.step(state, jnp.array([True]))
    with pytest.raises(ValueError, match=r"BraxEnv\.reset: rng must be one PRNG key, of shape \(2,\), got shape "
                                         r"\(3, 2\); jax\.vmap the reset"):
        env.reset(jax.random.split(jax.random.PRNGKey(0), 3))
    with pytest.raises(ValueError, match=r"rng must be one PRNG key, of shape \(\), got shape \(3,\)"):
        env.reset(jax.random.split(jax.random.key(0), 3))
    assert env.reset(jax.random.key(0)).obs.shape == (4,)  # a typed key is one key too
    wrapped = training.wrap(env, episode_length=5)  # vmapped by Brax: one action per environment
    s = wrapped.reset(jax.random.split(jax.random.PRNGKey(1), 3))
    assert wrapped.step(s, jnp.zeros((3, 1))).obs.shape == (3, 4)
