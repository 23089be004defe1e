"""Brax generalized and MJX rollouts of a chain exported by ``to_mjcf`` (or of a model of their own), for
``throughput`` and ``work_precision``.

Each returns one environment's ``rollout(q0, qd0, us) -> (q, qd)``, the final state after ``substeps`` steps of
``dt / substeps`` under each control ``us[t]`` (a ``fori_loop`` over the substeps when there are several).
"""

from __future__ import annotations

import os
import warnings

import jax

from lagrange.interop.mjcf import to_mjcf


def brax_rollout(chain, dt, substeps=1):
    """Brax generalized, semi-implicit Euler (MuJoCo's ``Euler``); ``chain`` may be the path of an MJCF file instead
    (Brax's own models: their timestep, ``dt`` unused)."""
    from brax.generalized import pipeline
    from brax.io import mjcf as bmjcf

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys = (bmjcf.load(chain) if isinstance(chain, (str, os.PathLike))
               else bmjcf.loads(to_mjcf(chain, timestep=dt / substeps, integrator="Euler")))

    def interval(state, u):
        if substeps == 1:
            return pipeline.step(sys, state, u), None
        return jax.lax.fori_loop(0, substeps, lambda i, s: pipeline.step(sys, s, u), state), None

    def rollout(q0, qd0, us):
        state, _ = jax.lax.scan(interval, pipeline.init(sys, q0, qd0), us)
        return state.q, state.qd

    return rollout


def mjx_rollout(chain, dt, integrator="Euler", substeps=1):
    """MJX with MuJoCo's ``integrator``; ``chain`` may be a ``mujoco.MjModel`` instead (its own options, ``dt`` and
    ``integrator`` unused)."""
    import mujoco
    from mujoco import mjx

    mx = mjx.put_model(chain if isinstance(chain, mujoco.MjModel) else
                       mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=dt / substeps, integrator=integrator)))

    def interval(d, u):
        d = d.replace(ctrl=u)
        if substeps == 1:
            return mjx.step(mx, d), None
        return jax.lax.fori_loop(0, substeps, lambda i, x: mjx.step(mx, x), d), None

    def rollout(q0, qd0, us):
        d, _ = jax.lax.scan(interval, mjx.make_data(mx).replace(qpos=q0, qvel=qd0), us)
        return d.qpos, d.qvel

    return rollout
