"""Which Runge-Kutta scheme does MuJoCo's RK4 run on a free joint, and what order do the candidates reach?

A free box (asymmetric inertia, off-centre, no gravity) tumbling: one ``mj_step`` with ``integrator="RK4"`` against
replicas built from MuJoCo's own ``mj_forward`` and ``mj_integratePos``: the published ``mj_RungeKutta`` (stages and
step from the start by the weighted velocity), the same with stage rotations composed in turn, and
Runge-Kutta-Munthe-Kaas (stage velocities through SO(3)'s inverse right Jacobian, lagrange's RK4 on trees). Then the
energy error of lagrange's RK4 (RKMK) and of the published scheme (RKMK without ``dexpinv``) on a free body carrying
a ball-jointed arm, over 1 s at h = 0.02, 0.01, 0.005: the observed orders.

    python -m research.mujoco_rk4_quaternions     # writes research/results/mujoco_rk4_quaternions.json (~1 min)
"""

from __future__ import annotations

import json
import pathlib

import jax
import mujoco
import numpy as np

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402

import lagrange as lg  # noqa: E402
from lagrange import rbda as spatial  # noqa: E402

BOX = """<mujoco><option integrator="RK4" timestep="0.05" gravity="0 0 0"/><worldbody><body><freejoint/>
<geom type="box" size="0.1 0.2 0.4" pos="0.3 0.1 0.2"/></body></worldbody></mujoco>"""
A = [[0.5], [0, 0.5], [0, 0, 1]]
B = [1 / 6, 1 / 3, 1 / 3, 1 / 6]


def one_step():
    model = mujoco.MjModel.from_xml_string(BOX)
    d = mujoco.MjData(model)
    q = np.array([0.1, 0.2, 0.3, 1, 0.2, 0.3, 0.1])
    q[3:] /= np.linalg.norm(q[3:])
    qd = np.array([0.3, -0.2, 0.5, 1.0, -2.0, 0.7])
    d.qpos[:], d.qvel[:] = q, qd
    mujoco.mj_step(model, d)
    ref = d.qpos.copy()
    h = model.opt.timestep

    def f(qp, qv):
        d.qpos[:], d.qvel[:] = qp, qv
        mujoco.mj_forward(model, d)
        return d.qvel.copy(), d.qacc.copy()

    def move(qp, v, scale):
        out = qp.copy()
        mujoco.mj_integratePos(model, out, v, scale)
        return out

    ks = [f(q, qd)]
    for i in range(1, 4):
        ks.append(f(move(q, sum(a * k[0] for a, k in zip(A[i - 1], ks)), h),
                    qd + h * sum(a * k[1] for a, k in zip(A[i - 1], ks))))
    published = move(q, sum(b * k[0] for b, k in zip(B, ks)), h)
    return {"mj_step_rk4_vs_published_scheme_max_abs_qpos": float(np.max(np.abs(published - ref)))}


def orders():
    tree = lg.Tree([lg.Body(2.0, (0.1, 0.3, 0.5), (0.1, 0.05, -0.2), joints=[lg.Free()]),
                    lg.Body(1.0, (0.05, 0.02, 0.04), (0.0, 0.0, -0.3), joints=[lg.Ball()], pos=(0.2, 0, 0))],
                   gravity=(0, 0, 0))
    q0 = jnp.array([0, 0, 0, 0.9, 0.1, 0.3, 0.2, 0.8, 0.3, -0.2, 0.1])
    qd0 = jnp.array([0.3, -0.2, 0.1, 2.0, -3.0, 1.5, 1.0, 0.5, -2.0])
    out = {}
    for name, correct in (("rkmk", spatial.dexpinv), ("published", lambda tree, theta, v: v)):
        original = spatial.dexpinv
        spatial.dexpinv = correct  # the published scheme is RKMK without the correction
        try:
            errs = []
            for h in (0.02, 0.01, 0.005):
                tr = lg.simulate(tree, q0, qd0, None, h, lg.RK4(), steps=int(round(1 / h)))
                E = sum(lg.energy(tree, tr.q, tr.qd))
                errs.append(float(jnp.max(jnp.abs(E - E[0]))))
        finally:
            spatial.dexpinv = original
        out[name] = {"energy_errors": errs, "orders": np.log2(np.array(errs[:-1]) / np.array(errs[1:])).tolist()}
    return out


if __name__ == "__main__":
    result = {"mujoco": mujoco.__version__, **one_step(), "energy_error_orders": orders()}
    path = pathlib.Path(__file__).parent / "results" / "mujoco_rk4_quaternions.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
