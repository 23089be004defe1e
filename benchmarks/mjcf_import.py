"""How exactly ``from_mjcf`` reproduces the planar models of dm_control, Gymnasium and Brax: errors against MuJoCo.

    python -m benchmarks.mjcf_import

For each model: the mass matrix (``mj_fullM``), the bias forces (``qfrc_bias - qfrc_passive``) and ``qacc`` at 32
random in-range states, and the worst of 8 rollouts of 100 steps with the model's own integrator
(``solver_of``) against ``mj_step`` under small random controls (a rollout on which MuJoCo meets a constraint is drawn
again, since the model is read without joint limits); errors relative, ``max|a - b| / max(1, max|b|)``, float64. A
model that ``from_mjcf`` refuses is listed as refused. Then the ten planar trees with a floating base (and the reacher
with its target) in free flight (:func:`free_flight`). Writes ``benchmarks/results/mjcf_import.{json,md}``.
"""

from __future__ import annotations

import pathlib

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import RESULTS, asset  # noqa: E402
from lagrange.interop.mjcf import from_mjcf, mujoco_rollout, solver_of  # noqa: E402
from lagrange.tasks.base import joint_kinds  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402

MODELS = {
    "dm_control acrobot": ("dm_control", "suite", "acrobot.xml"),
    "dm_control cartpole": ("dm_control", "suite", "cartpole.xml"),
    "dm_control pendulum": ("dm_control", "suite", "pendulum.xml"),
    "dm_control reacher": ("dm_control", "suite", "reacher.xml"),
    "Gymnasium inverted pendulum": ("gymnasium", "envs", "mujoco", "assets", "inverted_pendulum.xml"),
    "Gymnasium inverted double pendulum": ("gymnasium", "envs", "mujoco", "assets", "inverted_double_pendulum.xml"),
    "Gymnasium reacher": ("gymnasium", "envs", "mujoco", "assets", "reacher.xml"),
    "Brax inverted pendulum": ("brax", "envs", "assets", "inverted_pendulum.xml"),
    "Brax inverted double pendulum": ("brax", "envs", "assets", "inverted_double_pendulum.xml"),
}
TREES = {  # the planar trees with a floating base, and the reacher with its target: compared in free flight
    "Gymnasium hopper": ("gymnasium", "envs", "mujoco", "assets", "hopper.xml"),
    "Gymnasium half_cheetah": ("gymnasium", "envs", "mujoco", "assets", "half_cheetah.xml"),
    "Gymnasium walker2d": ("gymnasium", "envs", "mujoco", "assets", "walker2d.xml"),
    "Gymnasium reacher": ("gymnasium", "envs", "mujoco", "assets", "reacher.xml"),
    "dm_control hopper": ("dm_control", "suite", "hopper.xml"),
    "dm_control cheetah": ("dm_control", "suite", "cheetah.xml"),
    "dm_control walker": ("dm_control", "suite", "walker.xml"),
    "Brax hopper": ("brax", "envs", "assets", "hopper.xml"),
    "Brax half_cheetah": ("brax", "envs", "assets", "half_cheetah.xml"),
    "Brax walker2d": ("brax", "envs", "assets", "walker2d.xml"),
}


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def states(model, rng, k, scale):
    lo = np.where(model.jnt_limited, model.jnt_range[:, 0], -np.pi)
    hi = np.where(model.jnt_limited, model.jnt_range[:, 1], np.pi)
    return (rng.uniform(0.9 * scale * lo, 0.9 * scale * hi, (k, model.nq)), scale * rng.uniform(-2, 2, (k, model.nv)),
            rng.uniform(-2, 2, (k, model.nu)))


def term_errors(model, tree, q, qd, u) -> dict:
    """The worst relative errors of ``M``, the bias forces and ``qacc`` against MuJoCo's over the states ``(q, qd,
    u)`` (stacked), all of the tree's in one compiled call."""
    ours = jax.jit(jax.vmap(lambda q, qd, u: (lg.mass_matrix(tree, q), lg.bias_forces(tree, q, qd),
                                              lg.forward_dynamics(tree, q, qd, u if tree.m else None))))(
        jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u))
    data, err = mujoco.MjData(model), {"M": 0.0, "bias": 0.0, "qacc": 0.0}
    for k in range(len(q)):
        data.qpos[:], data.qvel[:], data.ctrl[:] = q[k], qd[k], u[k]
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        for name, a, b in zip(err, (o[k] for o in ours), (M, data.qfrc_bias - data.qfrc_passive, data.qacc)):
            err[name] = max(err[name], rel(a, b))
    return err


def rollout_error(model, tree, q0, qd0, us) -> float | None:
    """The relative error of ``len(us)`` steps of the model's own integrator against ``mj_step`` from ``(q0, qd0)``
    under the controls ``us``, or ``None`` where MuJoCo meets a constraint on the way (not the same system)."""
    xs, met = mujoco_rollout(model, q0, qd0, us)
    if met:
        return None
    solver, dt = solver_of(model)
    tr = lg.simulate(tree, jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us) if tree.m else None, dt, solver,
                     steps=len(us))
    return rel(np.concatenate([tr.q[1:], tr.qd[1:]], axis=1), xs[1:])


def measure(path: pathlib.Path) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    tree = from_mjcf(model, limits="ignore")
    rng = np.random.default_rng(0)
    err = term_errors(model, tree, *states(model, rng, 32, 1.0))
    rollouts = []
    while len(rollouts) < 8:  # a rollout on which MuJoCo meets a constraint is drawn again
        q0, qd0, _ = states(model, rng, 1, 0.05)
        e = rollout_error(model, tree, q0[0], qd0[0], rng.uniform(-0.3, 0.3, (100, model.nu)))
        rollouts += [] if e is None else [e]
    solver, dt = solver_of(model)
    return dict(joints=list(joint_kinds(tree)), integrator=type(solver).__name__, timestep=dt, **err,
                rollout=max(rollouts))


def free_flight(path: pathlib.Path) -> dict:
    """A planar tree with a floating base (or the reacher's forest) against MuJoCo with every constraint disabled:
    ``M``, bias and ``qacc`` at 12 random states (6 in range, 6 five times as far and as fast) and one 30-step
    rollout of the model's own integrator from a calm state (the tests' states)."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    tree = from_mjcf(path, limits="ignore", contact="ignore")
    rng = np.random.default_rng(0)
    q, qd, u = (np.concatenate(x) for x in zip(*(states(model, rng, 6, s) for s in (1.0, 5.0))))
    terms = max(term_errors(model, tree, q, qd, u).values())
    q0, qd0, _ = states(model, rng, 1, 0.05)
    rollout = rollout_error(model, tree, q0[0], qd0[0], rng.uniform(-0.3, 0.3, (30, model.nu)))
    return dict(planar=bool(tree.planar), terms=terms, rollout=rollout, constraint_met=rollout is None)


def main():
    rows = {}
    for name, parts in MODELS.items():
        try:
            rows[name] = measure(asset(*parts))
        except NotImplementedError as err:
            rows[name] = {"refused": str(err)}
        print(name, rows[name])
    rows["planar trees in free flight"] = trees = {name: free_flight(asset(*parts)) for name, parts in TREES.items()}
    print("planar trees:", trees)
    write_json(RESULTS / "mjcf_import.json", rows, indent=2)
    lines = ["| model | joints | integrator | M | bias | qacc | 100-step rollout |",
             "|---|---|---|---:|---:|---:|---:|"]
    for name, r in rows.items():
        if name == "planar trees in free flight":
            continue
        if "refused" in r:
            lines.append(f"| {name} | refused: its target is a second chain hanging from the world | | | | | |")
            continue
        joints = ", ".join("slide" if j == "prismatic" else "hinge" for j in r["joints"])
        lines.append(f"| {name} | {joints} | {r['integrator']} ({r['timestep']} s) | {r['M']:.0e} | "
                     f"{r['bias']:.0e} | {r['qacc']:.0e} | {r['rollout']:.0e} |")
    lines += ["", f"The {len(trees)} planar trees in free flight, worst over them: M, bias and qacc "
              f"{max(r['terms'] for r in trees.values()):.1e}, 30-step rollouts "
              f"{max(r['rollout'] for r in trees.values()):.1e} "
              f"(all planar: {all(r['planar'] for r in trees.values())})."]
    write_text(RESULTS / "mjcf_import.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
