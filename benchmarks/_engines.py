"""Brax generalized, MJX and MuJoCo C on a chain exported by ``to_mjcf`` (or on a model of their own), for
``throughput`` and ``work_precision``.

The JAX engines return one environment's ``rollout(q0, qd0, us) -> (q, qd)``, the final state after ``substeps``
steps of ``dt / substeps`` under each control ``us[t]`` (a ``fori_loop`` over the substeps when there are several).
"""

from __future__ import annotations

import os
import warnings

import jax
import numpy as np

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


class MujocoC:
    """MuJoCo C's ``mujoco.rollout`` with ``nthread`` threads, ``mujoco.MjModel`` ``model`` or ``model`` a chain written
    with ``timestep=dt`` and ``integrator``: :meth:`make` prepares a batch of rollouts."""

    def __init__(self, model, dt, integrator="Euler", nthread=2):
        import mujoco
        from mujoco import rollout

        self.mujoco, self.rollout = mujoco, rollout
        self.model = model if isinstance(model, mujoco.MjModel) else mujoco.MjModel.from_xml_string(
            to_mjcf(model, timestep=dt, integrator=integrator))
        self.datas = [mujoco.MjData(self.model) for _ in range(nthread)]
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mujoco.mj_stateSize(self.model, self.spec)

    def make(self, q0, qd0, us):
        """``run() -> states (B, T, nstate)``: the rollouts from ``q0, qd0 (B, n)`` under ``us (B, T, m)``."""
        B, n = q0.shape
        x0 = np.zeros((B, self.nstate))
        x0[:, 1 : 1 + n], x0[:, 1 + n : 1 + 2 * n] = q0, qd0
        ctrl = np.asarray(us) if self.model.nu else None
        nstep = us.shape[1]
        state = np.empty((B, nstep, self.nstate))

        def run():
            self.rollout.rollout(self.model, self.datas, x0, ctrl, nstep=nstep, state=state, persistent_pool=True)
            return state

        return run
