"""The Gymnasium adapter (lagrange/interop/gymnasium.py): it passes Gymnasium's own env checker, reproduces
the task exactly, truncates episodes at the horizon and renders the chain; an action that is None, NaN or of another
shape is refused by name with the state left as it was, and a state that turns non-finite ends the episode with
``info["nonfinite"]``."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

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


def test_gym_env_refuses_bad_actions_and_ends_a_blown_up_episode():
    import lagrange as lg
    from lagrange.interop.gymnasium import GymEnv
    from lagrange.tasks import ChainSwingup

    with pytest.raises(TypeError, match=r"GymEnv task must be a task of lagrange\.tasks \(an AbstractTask\), got None"):
        GymEnv(None)
    env = GymEnv(Acrobot.rods(horizon=5))
    env.reset(seed=0)
    q = env._state.q
    for action, message in ((None, r"action must be a real array of shape \(1,\) in \[-1, 1\] .* got None"),
                            ([np.nan], r"action must be finite, got \[nan\]; the state is unchanged"),
                            ([np.inf], r"action must be finite"),
                            ("push", r"action must be a real array .* got 'push'"),
                            ([True], r"action must be a real array"),
                            (np.zeros((1, 1)), r"action must have shape \(1,\) .* got shape \(1, 1\)"),
                            (0.5, r"action must have shape \(1,\) .* got shape \(\)")):
        with pytest.raises(ValueError, match=rf"GymEnv\.step: {message}"):
            env.step(action)
        assert env._state.q is q and env._t == 0  # nothing stepped
    # a gear of 1e300 blows the state up in one step: the episode ends (truncated) and says so
    blown = GymEnv(ChainSwingup(lg.systems.pendulum(gear=1e300), dt=0.05, horizon=5))
    blown.reset(seed=0)
    _, reward, terminated, truncated, info = blown.step(np.ones(1, np.float32))
    assert truncated and not terminated and info["nonfinite"] is True and not np.isfinite(reward)
    with pytest.raises(RuntimeError, match=r"ended with a non-finite state .* call reset\(\)"):
        blown.step(np.zeros(1, np.float32))
    blown.reset(seed=1)
    assert "nonfinite" not in blown.step(np.zeros(1, np.float32))[4]  # reset starts afresh
