"""Adapters that put the tasks of :mod:`lagrange.tasks` into other ecosystems' environment APIs.

- :class:`BraxEnv` (:mod:`lagrange.envs.brax_env`): a ``brax.envs.base.Env``, so Brax's PPO, SAC and APG
  trainers (``brax.training.agents.*``) run on a task unchanged.
- :class:`GymEnv` (:mod:`lagrange.envs.gym_env`): a ``gymnasium.Env`` with NumPy in and out.

Brax and Gymnasium are optional (test) dependencies: they are imported only when an adapter is first
used, so ``import lagrange`` and ``import lagrange.envs`` import neither.
"""

from __future__ import annotations

__all__ = ["BraxEnv", "GymEnv"]


def __getattr__(name):
    if name == "BraxEnv":
        from lagrange.envs.brax_env import BraxEnv

        return BraxEnv
    if name == "GymEnv":
        from lagrange.envs.gym_env import GymEnv

        return GymEnv
    raise AttributeError(f"module 'lagrange.envs' has no attribute {name!r}")
