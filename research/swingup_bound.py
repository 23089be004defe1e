"""How high can a swing-up return go? Multi-start trajectory optimisation of the swing-up.

    python -m research.swingup_bound            # acrobot: 64 starts x 8 swing-up times (about 10 minutes on 2 cores)
    python -m research.swingup_bound --task double_cartpole   # 64 starts x 8 times, about 7 minutes
    python -m research.swingup_bound --quick    # 16 starts, three swing-up times

The acrobot's reward is at most 10 per step and about 0 while the chain hangs (10 - pi^2), so a return
of R needs the chain near upright for roughly R / 10 of the 500 steps. This script asks what the task's
physics (two 1 m, 2.5 kg thin rods, elbow torque at most 25 N m, dt = 0.01 s) allow, independently of
any policy class or learner. For each swing-up time ``T`` (control steps), multi-start open-loop
optimisation of the first ``T`` actions (Adam on pre-tanh logits, BPTT through ``task.step`` from the
noise-free hanging start) maximises the return of those steps minus a terminal penalty
``w (|th|^2 + 0.05 |dth|^2)`` asking to arrive upright and slow. A start *arrives* when both of the
reward's angles (the first link's from upright, the elbow's bend) end within 0.2 rad (the ``balanced``
tolerance) and both speeds within 1 rad/s. The double cartpole (``--task double_cartpole``: two 1 m,
5.02 kg poles on a 10.47 kg cart, force at most 1000 N) is asked the same, with its cart as one more
coordinate: the penalty adds ``x^2 + 0.05 dx^2`` and arriving needs ``|x| <= 0.2`` m, ``|dx| <= 1`` m/s.

Since no step can earn more than 10, an episode that swings up along an arrived trajectory earns at
most ``swing part + 10 (500 - T)``: the *perfect-hold estimate* reported per ``T``. Its maximum over
``T`` is what the best swing-up found here is worth. Local optimisation of a chaotic swing-up finds
good optima, not provably the best, so this is a measured reference for the learners, not a proof.
Writes ``research/results/swingup_bound.json``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from benchmarks._cli import paper_task
from lagrange import tasks
from optim.checkpoint import write_json

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
# swing-up times T (control steps of 0.01 s) tried per task: (full run, --quick)
TIMES = {
    "acrobot": {False: [160, 170, 180, 190, 200, 210, 230, 260], True: [190, 210, 240]},
    "double_cartpole": {False: [40, 50, 60, 70, 80, 100, 120, 150], True: [60, 80, 100]},
}


def swing(task, logits):
    """Roll ``tanh(logits)`` (T,) out from the noise-free hanging start: ``(return, final pose, final speeds)``.

    The pose is the reward's angles (first link from upright, later links' bends), preceded by the
    cart position for a cart task; the speeds are the matching ``qd``."""
    n = task.chain.n
    s0 = tasks.TaskState(jnp.zeros(n, logits.dtype), jnp.zeros(n, logits.dtype))

    def body(s, z):
        a = jnp.tanh(z)[None]
        s2 = task.step(s, a)
        return s2, task.reward(s, a, s2)

    s, r = jax.lax.scan(body, s0, logits)
    pose = jnp.concatenate([s.q[:1], task.angles(s)]) if task.cart else task.angles(s)
    return r.sum(), pose, s.qd


def swing_loss(task, logits, weight: float):
    """What the optimiser minimises: minus the swing-up's return plus ``weight (|pose|^2 + 0.05 |speeds|^2)`` at its
    end."""
    ret, pose, speeds = swing(task, logits)
    return -ret + weight * (jnp.sum(pose**2) + 0.05 * jnp.sum(speeds**2))


def optimise_swing(task, T: int, starts: int, steps: int, weight: float, key):
    """Multi-start Adam (cosine-decayed 0.05 -> 5e-4) on ``T`` open-loop logits; returns (starts, T)."""

    def loss(z):
        return swing_loss(task, z, weight)

    opt = optax.adam(optax.cosine_decay_schedule(0.05, steps, 0.01))
    z = jax.random.normal(key, (starts, T))
    state = jax.vmap(opt.init)(z)

    @jax.jit
    def update(z, state):
        g = jax.vmap(jax.grad(loss))(z)
        u, state = jax.vmap(opt.update)(g, state)
        return optax.apply_updates(z, u), state

    for _ in range(steps):
        z, state = update(z, state)
    return z


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=sorted(TIMES), default="acrobot")
    p.add_argument("--quick", action="store_true", help="16 starts and three swing-up times")
    p.add_argument("--starts", type=int, default=None, help="random starts per swing-up time (default 64, quick 16)")
    p.add_argument("--steps", type=int, default=4000, help="Adam steps per start")
    p.add_argument("--weight", type=float, default=300.0, help="terminal penalty weight w")
    p.add_argument("--times", type=int, nargs="*", default=None, help="swing-up times T in control steps")
    p.add_argument("--out", default=None, help="default research/results/swingup_bound[_TASK].json")
    args = p.parse_args(argv)
    times = args.times or TIMES[args.task][args.quick]
    starts = args.starts or (16 if args.quick else 64)
    task = paper_task(args.task)  # on the rods
    out_path = args.out or str(RESULTS / ("swingup_bound.json" if args.task == "acrobot"
                                          else f"swingup_bound_{args.task}.json"))
    rows = []
    t_all = time.perf_counter()
    for i, T in enumerate(times):
        t0 = time.perf_counter()
        z = optimise_swing(task, T, starts, args.steps, args.weight, jax.random.PRNGKey(i))
        ret, pose, speeds = (np.asarray(x, np.float64) for x in jax.jit(jax.vmap(lambda zz: swing(task, zz)))(z))
        arrived = (np.abs(pose) <= 0.2).all(-1) & (np.abs(speeds) <= 1.0).all(-1)
        estimate = np.where(arrived, ret + 10.0 * (task.horizon - T), -np.inf)
        best = int(np.argmax(estimate))
        row = {
            "T": T, "seconds": T * task.dt, "starts": starts, "arrived": int(arrived.sum()),
            "perfect_hold_estimate": float(estimate[best]) if arrived.any() else None,
            "swing_part": float(ret[best]) if arrived.any() else None,
            "final_pose": pose[best].tolist() if arrived.any() else None,
            "final_speeds": speeds[best].tolist() if arrived.any() else None,
            "wall_seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        if arrived.any():
            print(f"T={T:4d} ({T * task.dt:.2f} s): {row['arrived']:3d}/{starts} arrive; best swing part "
                  f"{row['swing_part']:7.1f}, perfect-hold estimate {row['perfect_hold_estimate']:7.1f}; "
                  f"{row['wall_seconds']:.0f} s", flush=True)
        else:
            print(f"T={T:4d} ({T * task.dt:.2f} s): none of {starts} starts arrive; {row['wall_seconds']:.0f} s",
                  flush=True)
    found = [r for r in rows if r["perfect_hold_estimate"] is not None]
    out = {
        "task": args.task, "steps": args.steps, "weight": args.weight, "rows": rows,
        "fastest_arrival_seconds": min((r["seconds"] for r in found), default=None),
        "best_perfect_hold_estimate": max((r["perfect_hold_estimate"] for r in found), default=None),
        "wall_seconds": time.perf_counter() - t_all,
    }
    path = pathlib.Path(out_path)
    write_json(path, out, indent=2)
    print(f"fastest arrival {out['fastest_arrival_seconds']} s; best perfect-hold estimate "
          f"{out['best_perfect_hold_estimate']}; wrote {path}")
    return out


if __name__ == "__main__":
    main()
