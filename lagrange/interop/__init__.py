"""The trees and tasks of :mod:`lagrange` in other engines' and ecosystems' formats.

- :mod:`lagrange.interop.mjcf`: :func:`to_mjcf` writes a tree as an MJCF model, so MuJoCo, MJX and Brax
  simulate (or show) the very same system; :func:`from_mjcf` reads an MJCF model (dm_control's, Gymnasium's,
  Brax's, one's own), planar or 3-D, through MuJoCo's compiler as a tree with ``q = qpos``.
- :mod:`lagrange.interop.urdf`: :func:`from_urdf` reads a URDF robot as it ships (no mesh opened, inertias as
  written, fixed joints merged, a floating base on request) as a tree, exact against Pinocchio.
- :mod:`lagrange.interop.brax`: :class:`BraxEnv` puts a task of :mod:`lagrange.tasks` behind Brax's
  ``brax.envs.base.Env``, so Brax's PPO, SAC and APG trainers run on it; :func:`brax_training_compat`
  is the context in which Brax 0.14.2's trainers run on JAX 0.10.
- :mod:`lagrange.interop.gymnasium`: :class:`GymEnv` puts a task behind ``gymnasium.Env``, NumPy in and out.

Brax, Gymnasium and MuJoCo are optional (test) dependencies. Nothing here is imported until it is first
used: ``import lagrange`` and ``import lagrange.interop`` import none of them, and importing an adapter
changes no other module (in particular not ``jax``'s namespace)::

    from lagrange.interop import BraxEnv, brax_training_compat   # imports Brax
    from lagrange.interop.gymnasium import GymEnv                # imports Gymnasium
"""

from __future__ import annotations

import importlib

__all__ = ["BraxEnv", "GymEnv", "brax_training_compat", "from_mjcf", "from_urdf", "to_mjcf"]

_HOMES = {
    "BraxEnv": "lagrange.interop.brax",
    "brax_training_compat": "lagrange.interop.brax",
    "GymEnv": "lagrange.interop.gymnasium",
    "to_mjcf": "lagrange.interop.mjcf",
    "from_mjcf": "lagrange.interop.mjcf",
    "from_urdf": "lagrange.interop.urdf",
}


def __getattr__(name: str):
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'lagrange.interop' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
