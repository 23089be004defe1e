"""3-D trees beside MuJoCo C: semi-implicit Euler steps of dm_control's humanoid and Gymnasium's ant in free flight,
and of the ant on the ground.

    python -m benchmarks.trees3d              # B = 1024, 50 steps, float64
    python -m benchmarks.trees3d --batch 64   # smaller

For each model (constraints disabled, MuJoCo's Euler integrator, the tree read by ``from_mjcf``):
microseconds per environment-step of lagrange's ``simulate`` (``jax.vmap`` over the batch, one jitted program)
against MuJoCo C's ``mujoco.rollout`` with 2 threads on the same states and controls, the minimum of 3 repeats, both
in one process; the gradient of a loss of the final state through lagrange's rollout (``jax.grad``); and the
compile times of forward dynamics and of the rollout's gradient. On the ground (:func:`on_the_ground`): Gymnasium's
ant with DFlex's contact and limit laws at its 1/960 s substep beside MuJoCo C with its own contact at that step,
forward only. Writes ``benchmarks/results/trees3d.{json,md}`` (``--batch`` other than 1024: ``runs/benchmarks/``).

    python -m benchmarks.trees3d --mjx        # the ant on the ground beside MJX, forward and gradient (~4 minutes)

writes ``benchmarks/results/trees3d_mjx.{json,md}`` (:func:`beside_mjx`).
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mujoco import rollout  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import asset, gymnasium_model, outputs  # noqa: E402
from benchmarks._timing import median_time  # noqa: E402
from lagrange.interop.mjcf import from_mjcf  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402

MODELS = {"dm_control humanoid": lambda: asset("dm_control", "suite", "humanoid.xml"),
          "Gymnasium ant": lambda: gymnasium_model("ant")}


def free_flight(path):
    """MuJoCo's model with every constraint disabled and Euler, and the tree read from it."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    return model, from_mjcf(model, limits="ignore", contact="ignore")


def states(model, rng, B):
    """``B`` states near ``qpos0``: hinges moved by up to 0.5 rad, the free joint turned at random, speeds up to 1."""
    q = np.repeat(np.asarray(model.qpos0, float)[None], B, axis=0)
    for j in range(model.njnt):
        a = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            quat = rng.normal(size=(B, 4))
            q[:, a + 3: a + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        elif model.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            q[:, a] += rng.uniform(-0.5, 0.5, B)
    return q, rng.uniform(-1, 1, (B, model.nv))


def mujoco_c(model, q0, qd0, us):
    """MuJoCo C's ``mujoco.rollout`` of the ``B`` states ``(q0, qd0)`` under the controls ``us`` (``(B, T, nu)``) with
    2 threads: ``(seconds per env-step, the best of 3; the final qpos (B, nq))``."""
    B, T = us.shape[:2]
    datas = [mujoco.MjData(model) for _ in range(2)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.zeros((B, mujoco.mj_stateSize(model, spec)))
    x0[:, 1: 1 + model.nq], x0[:, 1 + model.nq: 1 + model.nq + model.nv] = q0, qd0
    state = np.empty((B, T, x0.shape[1]))
    seconds = median_time(lambda: rollout.rollout(model, datas, x0, us, nstep=T, state=state, persistent_pool=True),
                          repeats=3, best=True) / (B * T)
    return seconds, state[:, -1, 1: 1 + model.nq]


def measure(name, B, T):
    model, tree = free_flight(MODELS[name]())
    rng = np.random.default_rng(0)
    q0, qd0 = states(model, rng, B)
    us = rng.uniform(-1, 1, (B, T, model.nu))
    dt = float(model.opt.timestep)

    def final(q, qd, u):
        tr = lg.simulate(tree, q, qd, u, dt, lg.SemiImplicitEuler(), check=False)
        return tr.q[-1], tr.qd[-1]

    forward = jax.jit(jax.vmap(final), compiler_options=lg.compiler_options(tree))
    loss = lambda q, qd, u: jnp.sum(jnp.concatenate(final(q, qd, u)) ** 2)  # noqa: E731
    gradient = jax.jit(jax.vmap(jax.grad(loss, argnums=(0, 1, 2))), compiler_options=lg.compiler_options(tree))
    args = tuple(jnp.asarray(x) for x in (q0, qd0, us))
    t = time.perf_counter()
    jax.jit(lambda q, qd, u: lg.forward_dynamics(tree, q, qd, u, check=False),
            compiler_options=lg.compiler_options(tree)).lower(
        args[0][0], args[1][0], args[2][0, 0]).compile()
    compile_fd = time.perf_counter() - t
    t = time.perf_counter()
    gradient.lower(*args).compile()
    compile_grad = time.perf_counter() - t
    ours = median_time(forward, *args, repeats=3, best=True) / (B * T)
    ours_grad = median_time(gradient, *args, repeats=3, best=True) / (B * T)
    mj, qpos = mujoco_c(model, q0, qd0, us)
    err = float(np.max(np.abs(np.asarray(forward(*args)[0]) - qpos)))
    return dict(nq=model.nq, nv=model.nv, batch=B, steps=T, lagrange_us=ours * 1e6, lagrange_grad_us=ours_grad * 1e6,
                mujoco_c_us=mj * 1e6, speedup=mj / ours, compile_forward_dynamics_s=compile_fd,
                compile_rollout_gradient_s=compile_grad, final_qpos_max_abs_diff=err)


DFLEX_ANT = dict(contact=(4e4, 1e4, 3e3, 0.75), limits=(1e3, 10.0), dt=1.0 / 960)  # paper-facts.md, SHAC's Ant


def _ant_on_the_ground(B, T):
    """Gymnasium's ant at MuJoCo's Euler and DFlex's substep, the tree with DFlex's laws, and ``B`` standing states
    (hinges perturbed, small velocities) with ``T`` steps of random controls."""
    path = gymnasium_model("ant")
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    model.opt.timestep = DFLEX_ANT["dt"]
    tree = from_mjcf(path, contact=lg.PenaltyContact(*DFLEX_ANT["contact"]),
                     limits=lg.PenaltyLimits(*DFLEX_ANT["limits"]))
    rng = np.random.default_rng(0)
    q0 = np.repeat(np.asarray(model.qpos0, float)[None], B, axis=0)
    q0[:, 7:] += rng.uniform(-0.1, 0.1, (B, model.nq - 7))
    qd0 = rng.uniform(-0.25, 0.25, (B, model.nv))
    us = rng.uniform(-1, 1, (B, T, model.nu))
    return model, tree, (q0, qd0, us)


def _ground_rollout(tree):
    """One environment's final ``q`` after semi-implicit Euler steps at DFlex's ant substep under controls ``u``."""
    return lambda q, qd, u: lg.simulate(tree, q, qd, u, DFLEX_ANT["dt"], lg.SemiImplicitEuler(), check=False).q[-1]


def on_the_ground(B, T):
    """Gymnasium's ant standing on the ground at DFlex's contact and limit laws and substep (1/960 s), semi-implicit
    Euler, against MuJoCo C with its own contact on the same model at the same step (different contact models doing
    the same job): µs per env-step, forward."""
    model, tree, (q0, qd0, us) = _ant_on_the_ground(B, T)
    forward = jax.jit(jax.vmap(_ground_rollout(tree)), compiler_options=lg.compiler_options(tree))
    args = tuple(jnp.asarray(x) for x in (q0, qd0, us))
    ours = median_time(forward, *args, repeats=3, best=True) / (B * T)
    finite = bool(np.all(np.isfinite(np.asarray(forward(*args)))))
    mj, _ = mujoco_c(model, q0, qd0, us)
    return dict(nv=model.nv, batch=B, steps=T, dt=DFLEX_ANT["dt"], lagrange_us=ours * 1e6, mujoco_c_us=mj * 1e6,
                speedup=mj / ours, finite=finite)


def beside_mjx(B=64, T=20):
    """The ant on the ground as :func:`on_the_ground`, forward and the gradient of ``sum(q_T^2)`` with respect to
    ``(q0, qd0, us)``: lagrange beside MJX (its own contact, ``opt.iterations = 1``: with more iterations its solver's
    ``while_loop`` cannot be reverse-differentiated, mujoco#2259), µs per env-step, one process. MJX's gradient
    through contact compiles for minutes on a CPU, hence the small batch."""
    from mujoco import mjx

    model, tree, inputs = _ant_on_the_ground(B, T)
    model.opt.iterations = 1
    mx = mjx.put_model(model)

    def theirs(q, qd, u):
        d = mjx.make_data(mx).replace(qpos=q, qvel=qd)
        return jax.lax.scan(lambda d, ui: (mjx.step(mx, d.replace(ctrl=ui)), None), d, u)[0].qpos

    args = tuple(jnp.asarray(x) for x in inputs)
    out = dict(batch=B, steps=T, dt=DFLEX_ANT["dt"], mjx_iterations=1)
    engines = (("lagrange", _ground_rollout(tree), lg.compiler_options(tree)), ("mjx", theirs, None))
    for engine, final, options in engines:
        loss = lambda q, qd, u, final=final: jnp.sum(final(q, qd, u) ** 2)  # noqa: E731
        for kind, fn in (("forward", final), ("gradient", jax.grad(loss, argnums=(0, 1, 2)))):
            program = jax.jit(jax.vmap(fn), compiler_options=options)
            t = time.perf_counter()
            jax.block_until_ready(program(*args))
            out[f"{engine}_{kind}_first_call_s"] = time.perf_counter() - t
            out[f"{engine}_{kind}_us"] = median_time(program, *args, repeats=3, best=True) / (B * T) * 1e6
            print(engine, kind, f"{out[f'{engine}_{kind}_us']:.1f} µs/env-step", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--mjx", action="store_true", help="only the ant on the ground beside MJX, forward and gradient "
                                                       "(B = 64, 20 steps; benchmarks/results/trees3d_mjx.md)")
    args = ap.parse_args()
    if args.mjx:
        r = beside_mjx()
        folder = outputs(False)[0]
        write_json(folder / "trees3d_mjx.json", r, indent=2)
        table = ["`python -m benchmarks.trees3d --mjx`: Gymnasium's ant on the ground, DFlex's laws (lagrange) and "
                 f"MJX's own contact with opt.iterations = 1, semi-implicit Euler at 1/960 s, B = {r['batch']}, "
                 f"{r['steps']} steps, float64, µs per env-step", "",
                 "| engine | forward | gradient | gradient / forward | first call: forward, gradient |",
                 "|---|---:|---:|---:|---|"]
        for e in ("lagrange", "mjx"):
            table.append(f"| {e} | {r[e + '_forward_us']:.1f} | {r[e + '_gradient_us']:.1f} | "
                         f"{r[e + '_gradient_us'] / r[e + '_forward_us']:.1f} | "
                         f"{r[e + '_forward_first_call_s']:.0f} s, {r[e + '_gradient_first_call_s']:.0f} s |")
        table += ["", f"lagrange / MJX speed: forward {r['mjx_forward_us'] / r['lagrange_forward_us']:.0f}x, gradient "
                  f"{r['mjx_gradient_us'] / r['lagrange_gradient_us']:.0f}x"]
        write_text(folder / "trees3d_mjx.md", "\n".join(table) + "\n")
        print("\n".join(table))
        return
    rows = {name: measure(name, args.batch, args.steps) for name in MODELS}
    ground = on_the_ground(args.batch, args.steps)
    folder = outputs(args.batch != 1024)[0]
    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "trees3d.json", dict(rows, **{"Gymnasium ant on the ground": ground}), indent=2)
    lines = ["| model | nv | lagrange µs/env-step | MuJoCo C (2 threads) µs | lagrange / MuJoCo C speed | "
             "lagrange gradient µs | compile: forward dynamics, rollout gradient |",
             "|---|---:|---:|---:|---:|---:|---|"]
    for name, r in rows.items():
        lines.append(f"| {name} | {r['nv']} | {r['lagrange_us']:.1f} | {r['mujoco_c_us']:.1f} | {r['speedup']:.2f}x | "
                     f"{r['lagrange_grad_us']:.1f} | {r['compile_forward_dynamics_s']:.1f} s, "
                     f"{r['compile_rollout_gradient_s']:.1f} s |")
    lines += ["", "On the ground (DFlex's ant laws, semi-implicit Euler at 1/960 s; MuJoCo C with its own contact at "
              "the same step):", "",
              "| model | nv | lagrange µs/env-step | MuJoCo C (2 threads) µs | lagrange / MuJoCo C speed |",
              "|---|---:|---:|---:|---:|",
              f"| Gymnasium ant on the ground | {ground['nv']} | {ground['lagrange_us']:.1f} | "
              f"{ground['mujoco_c_us']:.1f} | {ground['speedup']:.2f}x |"]
    write_text(folder / "trees3d.md", "\n".join(lines) + "\n")
    print("\n".join(lines))
    for name, r in rows.items():
        print(f"{name}: final qpos within {r['final_qpos_max_abs_diff']:.1e} of MuJoCo C's")


if __name__ == "__main__":
    main()
