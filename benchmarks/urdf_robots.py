"""Every URDF of ``example-robot-data`` read by :func:`lagrange.interop.urdf.from_urdf`, against Pinocchio.

    python -m benchmarks.urdf_robots                 # every robot, fixed and floating base (about 10 minutes)
    python -m benchmarks.urdf_robots --only go2 panda
    python -m benchmarks.urdf_robots --speed-only     # a 7-dof arm and a 12-dof quadruped beside MuJoCo C, Pinocchio

For each ``.urdf`` of the package that Pinocchio reads with at least one joint, with its root welded and with a free
joint at the root (Pinocchio's ``JointModelFreeFlyer``): the mass matrix, the gravity forces and the velocity products
``C qd`` (lagrange's ``bias_forces`` less the joints' damping, against Pinocchio's ``rnea`` at zero acceleration) at two
random states, relative error ``max|a - b| / max(1, max|b|)``. Pinocchio's joints are matched by name (its order can
differ), a continuous joint's ``(cos, sin)`` taken from lagrange's angle, and a free joint's velocity turned from
MuJoCo's convention (linear velocity in the world frame) to Pinocchio's (in the body frame): ``qd = T v`` with
``T = diag(R, 1)``, so ``M = T^-T M_pin T^-1`` and the forces ``T^-T tau_pin`` (the bias also takes
``M_pin d(T^-1)/dt qd``). Also recorded: whether MuJoCo's compiler reads the file (:func:`from_mjcf`), and where it
does, the mass matrix and ``qfrc_bias - qfrc_passive`` against MuJoCo's (``q = qpos``); the warnings.

Needs ``example-robot-data`` (``pip install --no-deps example-robot-data``: 130 MB of robots; its cmake dependency is
not needed to read them) and Pinocchio (the test extra). Writes ``benchmarks/results/urdf_robots.json`` and ``.md``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time
import warnings
import xml.etree.ElementTree as ET

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import markdown_table  # noqa: E402
from lagrange.interop.urdf import from_urdf  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402

OUT = pathlib.Path(__file__).parent / "results" / "urdf_robots.json"


def package_root() -> pathlib.Path:
    """The ``robots`` folder of the installed ``example-robot-data`` (a cmeel package: under ``cmeel.prefix``)."""
    for base in map(pathlib.Path, sys.path):
        root = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if root.is_dir():
            return root
    raise SystemExit("example-robot-data is not installed: pip install --no-deps example-robot-data")


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b))))) if np.size(b) else 0.0


def compare(path: pathlib.Path, floating: bool, states: int = 2, seed: int = 0) -> dict:
    """lagrange against Pinocchio on one URDF: the worst errors of M, g and C qd over ``states`` random states."""
    import pinocchio as pin

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tree = from_urdf(path, floating_base=floating, motors=False)
    model = (pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating
             else pin.buildModelFromUrdf(str(path)))
    data = model.createData()
    joint_of = {j.find("child").get("link"): j.get("name") for j in ET.parse(path).getroot().findall("joint")}
    rng = np.random.default_rng(seed)
    worst = dict(M=0.0, g=0.0, Cqd=0.0)
    damping = np.concatenate([np.broadcast_to(np.asarray(j.damping, float), (j.nv,)) for j in tree.joints])
    terms = jax.jit(lambda q, qd: (lg.mass_matrix(tree, q), lg.gravity_forces(tree, q), lg.bias_forces(tree, q, qd)))
    for _ in range(states):
        q = np.asarray(tree.neutral()) + rng.uniform(-1.0, 1.0, tree.nq)
        qd = rng.uniform(-1.0, 1.0, tree.nv)
        qp, vp, perm, T = pin.neutral(model), np.zeros(model.nv), [], np.eye(model.nv)
        ap = np.zeros(model.nv)
        for k, body in enumerate(tree.bodies):
            qa, va = tree.qadr[k], tree.vadr[k]
            if floating and k == 0:
                q[3:7] /= np.linalg.norm(q[3:7])
                R = pin.Quaternion(*q[3:7]).toRotationMatrix()
                qp[:3], qp[3:7] = q[:3], [q[4], q[5], q[6], q[3]]  # Pinocchio's quaternion is (x, y, z, w)
                vp[:3], vp[3:6] = R.T @ qd[:3], qd[3:6]
                ap[:3] = -np.cross(qd[3:6], R.T @ qd[:3])  # d(R^T)/dt v_world at zero acceleration
                T[:3, :3] = R
                perm += list(range(6))
                continue
            jid = model.getJointId(joint_of[body.name])
            iq, iv = model.joints[jid].idx_q, model.joints[jid].idx_v
            qp[iq: iq + model.joints[jid].nq] = [np.cos(q[qa]), np.sin(q[qa])] if model.joints[jid].nq == 2 else q[qa]
            vp[iv] = qd[va]
            perm.append(iv)
        perm, Ti = np.array(perm), np.linalg.inv(T)
        pin.crba(model, data, qp)
        M_pin = np.triu(data.M) + np.triu(data.M, 1).T
        g_pin = pin.computeGeneralizedGravity(model, data, qp)
        c_pin = pin.rnea(model, data, qp, vp, ap) - g_pin
        M, g, bias = (np.asarray(x) for x in terms(jnp.asarray(q), jnp.asarray(qd)))
        worst["M"] = max(worst["M"], _rel(M, (Ti.T @ M_pin @ Ti)[np.ix_(perm, perm)]))
        worst["g"] = max(worst["g"], _rel(g, (Ti.T @ g_pin)[perm]))
        worst["Cqd"] = max(worst["Cqd"], _rel(bias - g - damping * qd,
                                              (Ti.T @ c_pin)[perm]))
    return dict(nq=tree.nq, nv=tree.nv, bodies=len(tree.bodies), pinocchio_nv=model.nv, **worst,
                warnings=sorted({str(w.message).split(": ", 1)[-1][:160] for w in caught}))


def against_mujoco(path: pathlib.Path, seed: int = 0) -> float:
    """The worst relative error of the mass matrix and of ``qfrc_bias - qfrc_passive`` against MuJoCo's own compile
    of the file (a fixed base, ``q = qpos``), at one random state."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tree = from_urdf(path, motors=False)
    rng = np.random.default_rng(seed)
    q, qd = rng.uniform(-1.0, 1.0, model.nq), rng.uniform(-1.0, 1.0, model.nv)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q, qd
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    terms = jax.jit(lambda q, qd: (lg.mass_matrix(tree, q), lg.bias_forces(tree, q, qd)))
    M_lg, bias = (np.asarray(x) for x in terms(jnp.asarray(q), jnp.asarray(qd)))
    return max(_rel(M_lg, M), _rel(bias, data.qfrc_bias - data.qfrc_passive))


def mujoco_reads(path: pathlib.Path) -> str | None:
    """``None`` where MuJoCo's compiler reads the file (:func:`from_mjcf`), else its error's first line."""
    from lagrange.interop.mjcf import from_mjcf

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from_mjcf(path, limits="ignore", contact="ignore")
        return None
    except Exception as e:  # noqa: BLE001 - recorded, not handled
        return f"{type(e).__name__}: {str(e).splitlines()[0][:120]}"


SPEED = {"xarm7 (fixed base)": ("xarm_description/urdf/xarm7.urdf", False),
         "go1 (floating base, free flight)": ("go1_description/urdf/go1.urdf", True)}


def speed(B: int = 1024, T: int = 20, dt: float = 0.002) -> list[dict]:
    """Microseconds per env-step of a 7-dof arm and a 12-dof quadruped (float64, semi-implicit Euler, no contact):
    lagrange's jitted ``jax.vmap`` of ``simulate`` (with :func:`lagrange.compiler_options`) beside MuJoCo C
    (``mujoco.rollout``, 2 threads, Euler, on the same tree written by ``to_mjcf``) and Pinocchio's ABA (one call
    per step, from Python: its per-call overhead included)."""
    import mujoco

    from benchmarks._engines import MujocoC
    from benchmarks._timing import median_time
    from lagrange.interop.mjcf import to_mjcf

    import pinocchio as pin

    rows, root = [], package_root()
    for name, (rel, floating) in SPEED.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tree = from_urdf(root / rel, floating_base=floating)
        model = mujoco.MjModel.from_xml_string(to_mjcf(tree, timestep=dt, integrator="Euler"))
        rng = np.random.default_rng(0)
        q0 = np.asarray(tree.neutral()) + rng.uniform(-0.3, 0.3, (B, tree.nq))
        if floating:
            q0[:, 3:7] /= np.linalg.norm(q0[:, 3:7], axis=1, keepdims=True)
        qd0, us = rng.uniform(-1, 1, (B, tree.nv)), rng.uniform(-1, 1, (B, T, tree.m))

        def final(q, qd, u):
            traj = lg.simulate(tree, q, qd, u, dt, lg.SemiImplicitEuler(), check=False)
            return traj.q[-1], traj.qd[-1]

        forward = jax.jit(jax.vmap(final), compiler_options=lg.compiler_options(tree))
        args = tuple(jnp.asarray(x) for x in (q0, qd0, us))
        jax.block_until_ready(forward(*args))
        ours = median_time(forward, *args, repeats=3, best=True) / (B * T)
        run = MujocoC(model, dt).make(q0, qd0, us)
        theirs = median_time(run, repeats=3, best=True) / (B * T)
        qpos = run()[:, -1, 1: 1 + tree.nq]
        pmodel = (pin.buildModelFromUrdf(str(root / rel), pin.JointModelFreeFlyer()) if floating
                  else pin.buildModelFromUrdf(str(root / rel)))
        pdata, q, v = pmodel.createData(), pin.neutral(pmodel), rng.uniform(-1, 1, pmodel.nv)
        aba = median_time(lambda: [pin.aba(pmodel, pdata, q, v, v) for _ in range(2000)], repeats=3, best=True) / 2000
        rows.append(dict(robot=name, nq=tree.nq, nv=tree.nv, batch=B, steps=T, lagrange_us=ours * 1e6,
                         mujoco_c_us=theirs * 1e6, pinocchio_aba_us=aba * 1e6, lagrange_over_mujoco=theirs / ours,
                         final_qpos_max_abs_diff_to_mujoco=float(np.max(np.abs(np.asarray(forward(*args)[0]) - qpos)))))
        print(f"{name}: lagrange {ours * 1e6:.2f} us, MuJoCo C {theirs * 1e6:.2f} us, Pinocchio ABA "
              f"{aba * 1e6:.2f} us per env-step", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="robots whose file name contains one of these")
    ap.add_argument("--out", type=pathlib.Path, default=OUT)
    ap.add_argument("--speed-only", action="store_true", help="only the arm's and the quadruped's speed")
    args = ap.parse_args(argv)
    if not args.speed_only:  # the correctness table, not a timing one: each robot's quantities compile once, at
        # LLVM's level 0 (faster to compile, the same IEEE operations); set before JAX's CPU client starts
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=0".strip()
    if args.speed_only:
        rows = speed()
        write_json(args.out.with_name("urdf_speed.json"), dict(rows=rows))
        args.out.with_name("urdf_speed.md").write_text(
            "`python -m benchmarks.urdf_robots --speed-only` (float64, B = 1024, 20 steps of 2 ms, semi-implicit Euler,"
            " no contact; us per env-step; 2 cores)\n\n" + markdown_table(rows, list(rows[0])))
        return
    import pinocchio as pin

    root = package_root()
    rows = []
    for path in sorted(root.rglob("*.urdf")):
        name = str(path.relative_to(root))
        if args.only and not any(s in path.name for s in args.only):
            continue
        try:
            njoints = pin.buildModelFromUrdf(str(path)).njoints - 1
        except Exception as e:  # noqa: BLE001
            rows.append(dict(robot=name, pinocchio=f"{type(e).__name__}: {str(e)[:100]}"))
            continue
        if njoints == 0:
            rows.append(dict(robot=name, pinocchio="no joint"))
            continue
        row = dict(robot=name, pinocchio="reads", mujoco=mujoco_reads(path) or "reads")
        if row["mujoco"] == "reads":
            row["against_mujoco"] = against_mujoco(path)
        t = time.perf_counter()
        for base in ("fixed", "floating"):
            try:
                r = compare(path, base == "floating")
                row[base] = r
                print(f"{name} {base}: nv {r['nv']} M {r['M']:.1e} g {r['g']:.1e} Cqd {r['Cqd']:.1e}", flush=True)
            except Exception as e:  # noqa: BLE001 - a failure is a row of the table
                row[base] = dict(error=f"{type(e).__name__}: {str(e)[:200]}")
                print(f"{name} {base}: {row[base]['error']}", flush=True)
        row["seconds"] = time.perf_counter() - t
        rows.append(row)
        jax.clear_caches()
    ok = [r for r in rows if r.get("pinocchio") == "reads"]
    summary = dict(
        files=len(rows), pinocchio_reads=len(ok),
        lagrange_reads={b: sum("error" not in r[b] for r in ok) for b in ("fixed", "floating")},
        mujoco_reads=sum(r["mujoco"] == "reads" for r in ok),
        worst_against_mujoco=max((r["against_mujoco"] for r in ok if "against_mujoco" in r), default=None),
        worst={b: {k: max((r[b][k] for r in ok if k in r[b]), default=None) for k in ("M", "g", "Cqd")}
               for b in ("fixed", "floating")},
    )
    write_json(args.out, dict(summary=summary, rows=rows))
    table = [dict(robot=r["robot"], nv=r["fixed"].get("nv", "-"),
                  **{f"{b} {k}": (f"{r[b][k]:.1e}" if k in r[b] else "error") for b in ("fixed", "floating")
                     for k in ("M", "g", "Cqd")}, mujoco="reads" if r["mujoco"] == "reads" else "refuses")
             for r in ok]
    args.out.with_suffix(".md").write_text(
        f"`python -m benchmarks.urdf_robots`: {summary}\n\n" + markdown_table(table, list(table[0]) if table else []))
    print(summary)


if __name__ == "__main__":
    main()
