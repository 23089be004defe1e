"""A task of :mod:`lagrange.tasks` as a Brax environment, and the context Brax's trainers need.

:class:`BraxEnv` wraps a task in ``brax.envs.base.Env``; Brax's trainers (``brax.training.agents.ppo``,
``sac``, ``apg``) then train on it unchanged. Brax 0.14.2's trainers call ``jax.device_put_replicated``,
which JAX 0.10 removed from its namespace, so run them inside :func:`brax_training_compat`::

    from brax.training.agents.ppo import train as ppo

    from lagrange.interop.brax import BraxEnv, brax_training_compat
    from lagrange.tasks import Cartpole

    env = BraxEnv(Cartpole.rods())
    with brax_training_compat():
        make_policy, params, metrics = ppo.train(environment=env, num_timesteps=100_000, episode_length=500)

Importing this module imports Brax (a test dependency of this project, not a runtime one) and changes no
other module: ``jax`` is touched only inside :func:`brax_training_compat`, and only for its duration.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import NamedTuple

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State

from lagrange.tasks import AbstractTask, TaskState

__all__ = ["BraxEnv", "PipelineState", "brax_training_compat"]


class PipelineState(NamedTuple):
    """The Brax ``pipeline_state`` of a task.

    Attributes:
        q (Float[Array, "nq"]): coordinates [rad; m for a cart].
        qd (Float[Array, "nv"]): velocities [rad/s; m/s for a cart].
        t (Int[Array, ""]): control steps into the episode.
        action (Float[Array, "m"] | None): the last action, for a task that observes it (``TaskState.action``: the
            Ant and the Humanoid); None for the others.
    """

    q: jax.Array
    qd: jax.Array
    t: jax.Array
    action: jax.Array | None = None


class BraxEnv(Env):
    """``task`` behind Brax's ``Env`` interface: ``reset(rng) -> State``, ``step(state, action) -> State``.

    The observation, reward and dynamics are the task's; ``done`` is 1 where the task ends early
    (``task.terminated``, a hopper that fell), and after ``task.horizon`` steps (``terminate_at_horizon=True``,
    the default). The
    step count lives in ``pipeline_state.t``, so Brax's ``AutoResetWrapper`` resets it with the rest of
    the state. With ``terminate_at_horizon=False`` the episode length is left to Brax's
    ``EpisodeWrapper`` (``episode_length=task.horizon`` in the trainers), which then flags the time
    limit as a truncation and lets PPO bootstrap there; with the default the horizon is a true end of
    the (finite-horizon) task and nothing is bootstrapped beyond it.

    Observations, rewards and ``done`` are in the dtype of the chain's parameters. Inside ``jit`` nothing can be
    raised: a NaN action, or a state that blows up, gives NaN observations and rewards, which a trainer must check.

    Usage: ``env = BraxEnv(Acrobot.rods())``, then ``env.reset(key)`` and ``env.step(state, action)``
    (jit and vmap them as any Brax environment), or pass ``environment=env`` to a Brax trainer inside
    :func:`brax_training_compat`. A 3-D task's trainer on a CPU wants YNNPACK's fusions off, as
    :func:`lagrange.compiler_options` turns them off for the library's own programs: Brax jits its programs itself,
    so set :data:`lagrange.compile.YNN_OFF_FLAG` in ``XLA_FLAGS`` before JAX starts (Brax's PPO on the humanoid:
    ~8x faster).

    Args:
        task: a task of :mod:`lagrange.tasks`.
        terminate_at_horizon: ``done`` is also 1 after ``task.horizon`` steps (True), or only at an early end
            (False).
    """

    def __init__(self, task: AbstractTask, *, terminate_at_horizon: bool = True):
        if not isinstance(task, AbstractTask):
            raise TypeError(f"BraxEnv task must be a task of lagrange.tasks (an AbstractTask), got {task!r:.80}")
        if not isinstance(terminate_at_horizon, bool):
            raise TypeError(f"BraxEnv terminate_at_horizon must be True or False, got {terminate_at_horizon!r}")
        self.task = task
        self.terminate_at_horizon = terminate_at_horizon
        self._dtype = jnp.result_type(task.chain.mass)

    def reset(self, rng: jax.Array) -> State:
        """The task's random start (Brax's ``VmapWrapper`` vmaps over a batch of keys).

        Args:
            rng: one PRNG key (a raw ``(2,)`` key or a typed one).

        Raises:
            ValueError: for a batch of keys.
        """
        typed = jax.dtypes.issubdtype(getattr(rng, "dtype", None) or jnp.result_type(rng), jax.dtypes.prng_key)
        one = () if typed else jnp.shape(jax.random.PRNGKey(0))
        if jnp.shape(rng) != one:
            raise ValueError(f"BraxEnv.reset: rng must be one PRNG key, of shape {one}, got shape {jnp.shape(rng)}; "
                             f"jax.vmap the reset over a batch of keys")
        s = self.task.reset(rng)
        zero = jnp.zeros((), self._dtype)
        ps = PipelineState(s.q, s.qd, jnp.zeros((), jnp.int32), s.action)
        return State(ps, self.task.observe(s).astype(self._dtype), zero, zero, {}, {})

    def step(self, state: State, action: jax.Array) -> State:
        """One control interval of the task (Brax's ``VmapWrapper`` vmaps the step over a batch).

        Args:
            state: the environment's state.
            action: one action, shape ``(action_size,)``, in ``[-1, 1]`` (clipped).

        Raises:
            ValueError: for an action of another shape.
            TypeError: for a boolean or complex action.
        """
        ps = state.pipeline_state
        s = TaskState(ps.q, ps.qd, ps.action)
        if jnp.shape(action) != (self.action_size,):
            raise ValueError(f"BraxEnv.step: action must have shape (action_size,) = ({self.action_size},), got "
                             f"{jnp.shape(action)}; jax.vmap the step (Brax's VmapWrapper) over a batch")
        kind = jnp.result_type(action)
        if kind == jnp.bool_ or jnp.issubdtype(kind, jnp.complexfloating):
            raise TypeError(f"BraxEnv.step: action must hold real numbers in [-1, 1], got dtype {kind}")
        action = jnp.asarray(action, self._dtype)
        s2 = self.task.step(s, action)
        reward = jnp.asarray(self.task.reward(s, action, s2), self._dtype)
        t = ps.t + 1
        can_end = self.task.ends_early  # static: a task that cannot end early traces no termination
        ended = self.task.terminated(s2) if can_end else None
        if self.terminate_at_horizon:
            done = ((t >= self.task.horizon) | ended if can_end else t >= self.task.horizon).astype(self._dtype)
        else:
            done = ended.astype(self._dtype) if can_end else jnp.zeros((), self._dtype)
        obs = self.task.observe(s2).astype(self._dtype)
        return state.replace(pipeline_state=PipelineState(s2.q, s2.qd, t, s2.action), obs=obs, reward=reward, done=done)

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


_REMOVED_FROM_JAX = ("device_put_replicated", "device_put_sharded")
"""The pmap-era placement functions JAX 0.10 removed from its public namespace (the implementations remain
in ``jax._src.api``); Brax 0.14.2's trainers and ``brax.training.pmap`` call ``jax.device_put_replicated``."""


@contextlib.contextmanager
def brax_training_compat() -> Iterator[None]:
    """Context in which Brax 0.14.2's trainers run on JAX 0.10: ``with brax_training_compat(): ppo.train(...)``.

    On entry, ``jax.device_put_replicated`` and ``jax.device_put_sharded`` are set to JAX's own
    implementations (``jax._src.api``), each only if ``jax`` lacks it; on exit (also on an exception) every
    name set here is removed again, so ``jax``'s namespace is exactly as it was before. A name ``jax``
    already has is left alone. Contexts nest. The names are module attributes, so while the context is
    open they are visible to every thread of the process.
    """
    from jax._src import api as _api

    installed = []
    try:
        for name in _REMOVED_FROM_JAX:
            if not hasattr(jax, name):
                setattr(jax, name, getattr(_api, name))
                installed.append(name)
        yield
    finally:
        for name in reversed(installed):
            vars(jax).pop(name, None)
