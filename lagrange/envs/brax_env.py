"""A task of :mod:`lagrange.tasks` as a Brax environment (``brax.envs.base.Env``).

Importing this module imports Brax (a test dependency of this project, not a runtime one).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State

from lagrange.tasks import TaskState

__all__ = ["BraxEnv", "PipelineState"]


class PipelineState(NamedTuple):
    """The Brax ``pipeline_state``: coordinates ``q`` (n,), velocities ``qd`` (n,) and the step count ``t`` ()."""

    q: jax.Array
    qd: jax.Array
    t: jax.Array


class BraxEnv(Env):
    """``task`` behind Brax's ``Env`` interface: ``reset(rng) -> State``, ``step(state, action) -> State``.

    The observation, reward and dynamics are the task's; ``done`` is 1 after ``task.horizon`` steps
    (``terminate_at_horizon=True``, the default) and 0 otherwise (the tasks never end early). The
    step count lives in ``pipeline_state.t``, so Brax's ``AutoResetWrapper`` resets it with the rest of
    the state. With ``terminate_at_horizon=False`` the episode length is left to Brax's
    ``EpisodeWrapper`` (``episode_length=task.horizon`` in the trainers), which then flags the time
    limit as a truncation and lets PPO bootstrap there; with the default the horizon is a true end of
    the (finite-horizon) task and nothing is bootstrapped beyond it.

    Observations, rewards and ``done`` are in the dtype of the chain's parameters.
    """

    def __init__(self, task, *, terminate_at_horizon: bool = True):
        if not isinstance(terminate_at_horizon, bool):
            raise TypeError(f"BraxEnv terminate_at_horizon must be True or False, got {terminate_at_horizon!r}")
        self.task = task
        self.terminate_at_horizon = terminate_at_horizon
        self._dtype = jnp.result_type(task.chain.mass)

    def reset(self, rng: jax.Array) -> State:
        s = self.task.reset(rng)
        zero = jnp.zeros((), self._dtype)
        ps = PipelineState(s.q, s.qd, jnp.zeros((), jnp.int32))
        return State(ps, self.task.observe(s).astype(self._dtype), zero, zero, {}, {})

    def step(self, state: State, action: jax.Array) -> State:
        ps = state.pipeline_state
        s = TaskState(ps.q, ps.qd)
        action = jnp.asarray(action, self._dtype)
        s2 = self.task.step(s, action)
        reward = jnp.asarray(self.task.reward(s, action, s2), self._dtype)
        t = ps.t + 1
        if self.terminate_at_horizon:
            done = (t >= self.task.horizon).astype(self._dtype)
        else:
            done = jnp.zeros((), self._dtype)
        obs = self.task.observe(s2).astype(self._dtype)
        return state.replace(pipeline_state=PipelineState(s2.q, s2.qd, t), obs=obs, reward=reward, done=done)

    @property
    def observation_size(self) -> int:
        return int(self.task.observation_size)

    @property
    def action_size(self) -> int:
        return int(self.task.action_size)

    @property
    def backend(self) -> str:
        return "lagrange"

    @property
    def dt(self) -> float:
        """Control interval [s]."""
        return float(self.task.dt)


def _restore_jax_names_brax_needs() -> None:
    """Brax 0.14.2's trainers call ``jax.device_put_replicated`` / ``jax.device_put_sharded``, which JAX
    0.10 removed from its public namespace (the implementations remain in ``jax._src.api``). Put them
    back, only if missing, so that the trainers run unchanged on this project's pinned versions."""
    from jax._src import api as _api

    for name in ("device_put_replicated", "device_put_sharded"):
        try:
            getattr(jax, name)
        except AttributeError:
            setattr(jax, name, getattr(_api, name))


_restore_jax_names_brax_needs()
