"""A task of :mod:`lagrange.tasks` as a Gymnasium environment (NumPy in and out).

:class:`GymEnv` wraps a task in ``gymnasium.Env``, for code written against Gymnasium's API::

    from lagrange.interop.gymnasium import GymEnv
    from lagrange.tasks import Acrobot

    env = GymEnv(Acrobot.rods(), render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    frame = env.render()  # (240, 320, 3) uint8

Importing this module imports Gymnasium and Matplotlib (Gymnasium is a test dependency of this
project, not a runtime one) and changes no other module.
"""

from __future__ import annotations

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces

from lagrange.plotting import chain_outline, chain_reach
from lagrange.tasks import AbstractTask, TaskState

__all__ = ["GymEnv"]


class GymEnv(gym.Env):
    """``task`` behind the ``gymnasium.Env`` interface, one environment, NumPy in and out.

    - ``observation_space``: ``Box(-inf, inf, (task.observation_size,), float32)``;
      ``action_space``: ``Box(-1, 1, (task.action_size,), float32)`` (the task clips and scales by the gear).
    - ``reset(seed=..., options=None) -> (obs, {})``: the task's random start, drawn from a JAX key taken
      from the environment's ``np_random`` (so a seed reproduces the episode).
    - ``step(action) -> (obs, reward, terminated, truncated, info)``: ``terminated`` is the task's early end
      (``task.terminated``: a hopper that fell; never for the swing-ups); ``truncated`` becomes True after
      ``task.horizon`` steps. ``info`` holds the
      coordinates ``q`` and velocities ``qd`` (float64 NumPy arrays). The action must be a finite real array of
      shape ``(action_size,)``: None, NaN or another shape raise ``ValueError`` and leave the state as it was. A
      state that turns non-finite (the simulation blew up) ends the episode: ``truncated`` is True and
      ``info["nonfinite"]`` is True, and ``step`` refuses to go on until ``reset``.
    - ``render()`` (``render_mode="rgb_array"``): an RGB frame (H, W, 3) uint8 of the chain drawn from
      :func:`lagrange.positions` with Matplotlib's Agg backend.

    The simulation runs in the dtype of the chain's parameters; observations are cast to float32.

    Args:
        task: a task of :mod:`lagrange.tasks`.
        render_mode: None, or ``"rgb_array"``.
        frame_size: ``(width, height)`` of a rendered frame in pixels, each >= 16.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, task: AbstractTask, *, render_mode: str | None = None, frame_size: tuple[int, int] = (320, 240)):
        if not isinstance(task, AbstractTask):
            raise TypeError(f"GymEnv task must be a task of lagrange.tasks (an AbstractTask), got {task!r:.80}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"GymEnv render_mode must be None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        if (len(frame_size) != 2 or any(isinstance(v, bool) or not isinstance(v, int) or v < 16
                                         for v in frame_size)):
            raise ValueError(f"GymEnv frame_size must be (width, height) integers >= 16, got {frame_size!r}")
        self.task = task
        self.render_mode = render_mode
        self.frame_size = tuple(frame_size)
        self.metadata = {**self.metadata, "render_fps": max(1, int(round(1.0 / task.dt)))}
        self.observation_space = spaces.Box(-np.inf, np.inf, (task.observation_size,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (task.action_size,), np.float32)
        self._dtype = jnp.result_type(task.chain.mass)

        def _reset(key):
            s = task.reset(key)
            return s, task.observe(s)

        def _step(s, a):
            s2 = task.step(s, a)
            return s2, task.observe(s2), task.reward(s, a, s2), task.terminated(s2)

        self._reset_fn = jax.jit(_reset)
        self._step_fn = jax.jit(_step)
        self._positions = jax.jit(lambda q: chain_outline(task.chain, q))
        self._state: TaskState | None = None
        self._t = 0
        self._broken = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode from the task's random start.

        Args:
            seed: seeds the environment's ``np_random``, from which the JAX key of the start is drawn.
            options: unused (Gymnasium's interface).

        Returns:
            ``(obs, {})``, the observation as float32.
        """
        super().reset(seed=seed)
        key = jax.random.PRNGKey(int(self.np_random.integers(0, 2**31 - 1)))
        self._state, obs = self._reset_fn(key)
        self._t, self._broken = 0, False
        return np.asarray(obs, np.float32), {}

    def step(self, action):
        """One control interval; see the class docstring.

        Args:
            action: a finite real array of shape ``(action_size,)``, in ``[-1, 1]`` (clipped).

        Returns:
            ``(obs, reward, terminated, truncated, info)``.

        Raises:
            RuntimeError: before :meth:`reset`, and after an episode ended by a non-finite state.
            ValueError: for an action that is not a finite real array of shape ``(action_size,)`` (None, NaN, a
                batch); the state is left as it was.
        """
        if self._state is None:
            raise RuntimeError("GymEnv.step called before reset()")
        if self._broken:
            raise RuntimeError("GymEnv.step: the episode ended with a non-finite state (info['nonfinite']); call "
                               "reset() before stepping again")
        a = self._check_action(action)
        self._state, obs, reward, terminated = self._step_fn(self._state, jnp.asarray(a, self._dtype))
        self._t += 1
        truncated = self._t >= self.task.horizon
        info = {"q": np.asarray(self._state.q, np.float64), "qd": np.asarray(self._state.qd, np.float64)}
        if not (np.all(np.isfinite(info["q"])) and np.all(np.isfinite(info["qd"])) and np.isfinite(reward)):
            self._broken, truncated = True, True  # the simulation blew up: end the episode, say so
            info["nonfinite"] = True
        with np.errstate(over="ignore", invalid="ignore"):  # a blown-up observation overflows float32: inf
            obs = np.asarray(obs, np.float32)
        return obs, float(reward), bool(terminated), bool(truncated), info

    def _check_action(self, action) -> np.ndarray:
        shape = self.action_space.shape
        try:
            a = np.asarray(action)
            ok = a.dtype != np.bool_ and (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"GymEnv.step: action must be a real array of shape {shape} in [-1, 1] (action_space "
                             f"{self.action_space}), got {action!r}")
        if a.shape != shape:
            raise ValueError(f"GymEnv.step: action must have shape {shape} (action_space {self.action_space}), got "
                             f"shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"GymEnv.step: action must be finite, got {a.tolist()}; the state is unchanged")
        return a.astype(np.float64)

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("GymEnv.render called without a render_mode; pass render_mode='rgb_array'")
            return None
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        if self._state is None:
            raise RuntimeError("GymEnv.render called before reset()")
        pts = np.asarray(self._positions(self._state.q), np.float64)
        reach = chain_reach(self.task.chain) + 0.2
        w, h = self.frame_size
        dpi = 80
        fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
        canvas = FigureCanvasAgg(fig)
        ax = fig.add_axes((0, 0, 1, 1))
        cx = pts[0, 0] if getattr(self.task, "cart", False) else 0.0
        half_w = max(reach, reach * w / h)
        ax.set_xlim(cx - half_w, cx + half_w)
        ax.set_ylim(-reach, reach)
        ax.set_aspect("equal", adjustable="box")
        ax.axis("off")
        ax.axhline(0.0, color="0.75", lw=1)
        ax.plot(pts[:, 0], pts[:, 1], "o-", lw=4, color="tab:blue", mfc="k", ms=5)
        canvas.draw()
        frame = np.asarray(canvas.buffer_rgba())[..., :3].copy()
        return frame
