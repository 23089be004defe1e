"""The Brax and Gymnasium adapters (lagrange/interop): they reproduce the task exactly, end episodes at the
horizon, run in the ecosystems' own machinery (Brax's PPO trainer, Gymnasium's env checker), and importing
them changes no other module."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange.tasks import make_task


def _run_fresh(code: str) -> None:
    """Run ``code`` in a fresh interpreter (nothing imported yet); fails with its stderr if it fails."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


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


def test_importing_lagrange_and_lagrange_interop_imports_no_optional_engine():
    """Brax, Gymnasium and MuJoCo are loaded by the adapter that needs them, on first use, never before."""
    _run_fresh("""
        import sys
        import lagrange, lagrange.interop, lagrange.interop.mjcf, lagrange.tasks
        assert {"BraxEnv", "GymEnv", "brax_training_compat", "to_mjcf"} <= set(dir(lagrange.interop))
        assert lagrange.interop.to_mjcf is lagrange.interop.mjcf.to_mjcf
        loaded = [m for m in sys.modules if m.split(".")[0] in ("brax", "gymnasium", "mujoco")]
        assert not loaded, loaded
    """)


def test_importing_the_adapters_changes_no_other_module():
    """Importing lagrange.interop.brax and lagrange.interop.gymnasium leaves every module that was loaded before
    as it was (same names bound to the same objects), ``jax`` above all: in particular it does not put back
    ``jax.device_put_replicated``. The engines' own imports come first, so that what they do to ``jax`` (Brax
    imports ``jax.flatten_util``, which binds it on ``jax``) is not counted; the only names allowed to appear
    are the new submodules bound on their parent packages."""
    _run_fresh("""
        import sys
        import jax
        import brax.envs.base, gymnasium, lagrange.tasks, lagrange.kinematics

        def namespaces():  # every loaded module but this script's own (__main__)
            return {name: {k: id(v) for k, v in vars(m).items()}
                    for name, m in list(sys.modules.items()) if m is not None and m is not sys.modules["__main__"]}

        had = {name: hasattr(jax, name) for name in ("device_put_replicated", "device_put_sharded")}
        jax_names, before = sorted(dir(jax)), namespaces()
        import lagrange.interop.brax, lagrange.interop.gymnasium
        after = namespaces()
        assert sorted(dir(jax)) == jax_names, set(dir(jax)) ^ set(jax_names)
        assert {name: hasattr(jax, name) for name in had} == had, had
        changed = {}
        for name, ns in before.items():
            new = {k for k in after[name].keys() - ns.keys() if f"{name}.{k}" not in sys.modules}
            rebound = {k for k in ns if after[name].get(k) != ns[k]}
            if new or rebound:
                changed[name] = (sorted(new), sorted(rebound))
        assert not changed, changed
    """)


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


# ---------------------------------------------------------------------------------------------
# Brax


def test_brax_env_reproduces_the_task_and_ends_at_the_horizon():
    from brax.envs.wrappers import training

    from lagrange.interop.brax import BraxEnv

    task = dataclasses.replace(make_task("double_cartpole"), horizon=7)
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

    task = dataclasses.replace(make_task("cartpole"), horizon=50)
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


# ---------------------------------------------------------------------------------------------
# Gymnasium


def test_gym_env_passes_check_env():
    from gymnasium.utils.env_checker import check_env

    from lagrange.interop.gymnasium import GymEnv

    for name in ("acrobot", "cartpole", "double_cartpole"):
        check_env(GymEnv(make_task(name), render_mode="rgb_array"), skip_render_check=False)


def test_gym_env_reproduces_the_task_truncates_at_the_horizon_and_renders():
    from lagrange.interop.gymnasium import GymEnv

    task = dataclasses.replace(make_task("acrobot"), horizon=5)
    env = GymEnv(task, render_mode="rgb_array")
    obs, info = env.reset(seed=3)
    obs_again, _ = GymEnv(task).reset(seed=3)
    np.testing.assert_array_equal(obs, obs_again)  # the seed reproduces the start
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape and info == {}
    actions = np.array([[0.3], [-2.0], [1.0], [0.0], [0.7]], np.float32)
    q = jnp.asarray(env._state.q)
    qd = jnp.asarray(env._state.qd)
    from lagrange.tasks import TaskState

    s = TaskState(q, qd)
    for t, a in enumerate(actions):
        obs, reward, terminated, truncated, info = env.step(a)
        s2 = task.step(s, jnp.asarray(a, jnp.float64))
        np.testing.assert_allclose(reward, float(task.reward(s, a, s2)), rtol=1e-12)
        np.testing.assert_array_equal(obs, np.asarray(task.observe(s2), np.float32))
        np.testing.assert_allclose(info["q"], np.asarray(s2.q), rtol=1e-12)
        assert terminated is False and truncated is (t == 4)
        s = s2
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    # The chain is drawn: blue-ish pixels of the links exist, and the frame is not uniform.
    blue = (frame[..., 2] > 150) & (frame[..., 0] < 100)
    assert blue.sum() > 100 and frame.std() > 10
