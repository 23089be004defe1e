"""How does DFlex's float32 arithmetic about the world's origin degrade with the distance a robot has run?

    python -m research.dflex_precision        # DFlex's humanoid, ant and SNU humanoid, a few seconds

DFlex (the SHAC release's simulator) forms the joint-space mass matrix ``H = J^T M J`` from spatial inertias and
motion subspaces taken about the world's origin, in float32; a robot that runs along +x carries its bodies' ``m x``
and ``m x^2`` terms into every entry. lagrange takes its spatial vectors about the tree's own reference point (the
root), so its accuracy does not depend on where the robot is. This emulates DFlex's arithmetic in NumPy: at random
poses (hinges uniform within their ranges, the root turned up to 0.3 rad, its origin at ``x`` along the world's x
axis), each link's frame exact (lagrange's kinematics in float64), then in float32 the world-origin spatial inertias,
the subspaces moved to the origin, ``H`` summed link by link, armature added, factorised and solved for a random force.
Against the float64 solve at the same pose it reports the hinge accelerations' median and 90th-percentile relative
errors and the share of poses whose float32 Cholesky factorisation fails. An emulation of DFlex's arithmetic, not a
DFlex run. Writes ``research/results/dflex_precision.json``.
"""

from __future__ import annotations

import os

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from lagrange.rbda.kinematics import Kinematics, link_inertias  # noqa: E402
from lagrange.tasks import Ant, Humanoid, SNUHumanoid  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402
from research._cli import REPO  # noqa: E402

DISTANCES = (0.0, 10.0, 50.0, 100.0, 125.0, 150.0, 175.0, 200.0)
POSES = 100


def _skew(x):
    return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], x.dtype)


def _random_q(tree, rng, x):
    q = np.array(tree.neutral(), float)
    axis = rng.normal(size=3)
    angle = rng.uniform(0, 0.3)
    turn = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis / np.linalg.norm(axis)])
    w0, v0 = q[3], q[4:7]
    w1, v1 = turn[0], turn[1:]
    q[3:7] = np.concatenate([[w0 * w1 - v0 @ v1], w0 * v1 + w1 * v0 + np.cross(v0, v1)])
    q[0] += x
    for k, j in enumerate(tree.joints[1:], start=1):
        a = tree.qadr[k]
        if j.nq == 1:
            lo, hi = j.range if j.range is not None else (-0.5, 0.5)
            q[a] = rng.uniform(lo, hi)
        elif j.nq == 4:  # a ball: a random turn of up to 0.5 rad
            ax = rng.normal(size=3)
            t = rng.uniform(0, 0.5)
            q[a: a + 4] = np.concatenate([[np.cos(t / 2)], np.sin(t / 2) * ax / np.linalg.norm(ax)])
    return q


def _world_float32_H(tree, q):
    """DFlex's ``H`` in float32 about the world's origin, from the exact link frames."""
    k = Kinematics(tree, jnp.asarray(q))
    st = k.structure
    mass, com, Ic = (np.asarray(x) for x in link_inertias(st))
    R, p, o = (np.asarray(x) for x in (k.R, k.p, k.o))
    S = np.asarray(k.S)  # (nv, 6) about the reference point o (of each dof's link's tree)
    f32 = np.float32
    H = np.zeros((tree.nv, tree.nv), f32)
    o_dof = o[st.dof_link]  # the reference point of each dof
    w, v = S[:, :3], S[:, 3:]
    S0 = np.concatenate([w, v - np.cross(w, o_dof)], axis=1).astype(f32)  # about the world's origin
    path = np.asarray(st.path)  # (links, links): link i on the path of link j -> path[j, i]
    for link in range(st.n):
        m = f32(mass[link])
        c = (o[link] + p[link] + R[link] @ com[link]).astype(f32)  # the centre of mass in the world
        Jc = (R[link] @ Ic[link] @ R[link].T).astype(f32)
        cx = _skew(c)
        I0 = np.block([[Jc + m * cx @ cx.T, m * cx], [m * cx.T, m * np.eye(3, dtype=f32)]]).astype(f32)
        dofs = np.flatnonzero(path[link][st.dof_link] > 0)  # the dofs on the link's path from the world
        J = S0[dofs]  # (d, 6)
        H[np.ix_(dofs, dofs)] += (J @ I0 @ J.T).astype(f32)
    armature = np.concatenate([np.full(j.nv, float(j.armature)) for j in tree.joints]).astype(f32)
    return H + np.diag(armature)


def measure(name, tree, seed=0):
    rng = np.random.default_rng(seed)
    hinges = np.array([tree.vadr[k] for k, j in enumerate(tree.joints) if j.nv == 1])
    rows = []
    for x in DISTANCES:
        errs, failed = [], 0
        for _ in range(POSES):
            q = _random_q(tree, rng, x)
            H64 = np.asarray(lg.mass_matrix(tree, jnp.asarray(q)))
            tau = rng.normal(size=tree.nv) * np.sqrt(np.diag(H64))  # forces on the scale of each dof's inertia
            ref = np.linalg.solve(H64, tau)
            H32 = _world_float32_H(tree, q)
            try:
                L = np.linalg.cholesky(H32)
                if not np.all(np.isfinite(L)):
                    raise np.linalg.LinAlgError
            except np.linalg.LinAlgError:
                failed += 1
                continue
            sol = np.linalg.solve(L.T.astype(np.float64), np.linalg.solve(L.astype(np.float64), tau.astype(np.float32)
                                                                          .astype(np.float64)))
            errs.append(np.abs(sol[hinges] - ref[hinges]) / np.maximum(np.abs(ref[hinges]), 1e-12))
        e = np.concatenate(errs) if errs else np.array([np.nan])
        rows.append(dict(x=x, median=float(np.median(e)), p90=float(np.percentile(e, 90)),
                         cholesky_failed=failed / POSES))
        print(f"{name:13s} x = {x:5.0f} m: hinge qdd error median {rows[-1]['median']:.2e}, 90% "
              f"{rows[-1]['p90']:.2e}; Cholesky failed {failed}/{POSES}", flush=True)
    return rows


def main():
    out = {}
    for name, task in (("humanoid", Humanoid), ("ant", Ant), ("snu_humanoid", SNUHumanoid)):
        out[name] = measure(name, task.model())
    write_json(os.path.join(REPO, "research", "results", "dflex_precision.json"), out)


if __name__ == "__main__":
    main()
