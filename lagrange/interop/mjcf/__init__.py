"""MJCF in and out: read the models people hold as MJCF (and URDF), export any tree so MuJoCo and Brax simulate it, and
run MuJoCo on a model for cross-checks.

- :mod:`~lagrange.interop.mjcf.reader`: :func:`from_mjcf`, a model through MuJoCo's own compiler as a
  :class:`lagrange.Tree` with ``q = qpos``, ``qd = qvel``, ``u = ctrl`` (the docs' "Importing MJCF");
- :mod:`~lagrange.interop.mjcf.writer`: :func:`to_mjcf`, a tree as an MJCF string (needs neither MuJoCo nor Brax);
- :mod:`~lagrange.interop.mjcf.runtime`: :func:`mujoco_rollout` steps MuJoCo itself, :func:`solver_of` names the
  integrator that reproduces its ``mj_step``.

Reading and running need MuJoCo (``pip install -e ".[mjcf]"``), imported when first called.
"""

from lagrange.interop.mjcf.reader import LIMITS, from_mjcf
from lagrange.interop.mjcf.runtime import mujoco_rollout, solver_of
from lagrange.interop.mjcf.writer import INTEGRATORS, to_mjcf

__all__ = ["INTEGRATORS", "LIMITS", "from_mjcf", "mujoco_rollout", "solver_of", "to_mjcf"]
