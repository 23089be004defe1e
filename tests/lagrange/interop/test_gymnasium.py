"""The Gymnasium adapter (lagrange/interop/gymnasium.py): it passes Gymnasium's own env checker, reproduces
the task exactly, truncates episodes at the horizon and renders the chain."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.tasks import PAPER_TASKS, Acrobot


def test_gym_env_passes_check_env():
    from gymnasium.utils.env_checker import check_env

    from lagrange.interop.gymnasium import GymEnv

    for name in ("acrobot", "cartpole", "double_cartpole"):
        check_env(GymEnv(PAPER_TASKS[name].rods(), render_mode="rgb_array"), skip_render_check=False)


def test_gym_env_reproduces_the_task_truncates_at_the_horizon_and_renders():
    from lagrange.interop.gymnasium import GymEnv

    task = Acrobot.rods(horizon=5)
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
