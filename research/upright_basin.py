"""How far from upright can the task's torque limit still bring the chain back? Saturated LQR at the top.

    python -m research.upright_basin                   # the acrobot (seconds)
    python -m research.upright_basin --task double_cartpole
    python -m research.upright_basin --bodies brax_v1     # on the authors' Brax v1 bodies

The swing-up tasks end in a balance that "balanced" judges to 0.2 rad. This script asks how much of that
0.2 rad a simple stabilising controller can recover from with the task's own actuator limit. It linearises
``task.step`` (one control interval, RK4, by ``jax.jacfwd``) at the upright equilibrium, solves the discrete
LQR for ``Q = diag(1 on q, 0.01 on qd)`` and ``R = r`` and measures the basin (all :mod:`lagrange.control`): runs
``u = clip(-K dx, -1, 1)`` (``dx`` with wrapped angles) through the nonlinear ``task.step`` from a lean of
``d`` rad at one joint at a time (joint 1 leans the whole straight chain, a later joint bends it there),
starting at rest. A start "recovers" when, after ``--steps`` control steps, every coordinate is within 1e-3
(rad, m) and every velocity within 1e-3 of upright at rest. Reported: per joint, the largest ``d`` on the grid
up to which every start recovers (``every_lean_recovered``: the whole grid did); the closed-loop spectral radius of the
linear model (< 1: stable); the gain. A large ``r`` gives the smallest gains (least saturation); LQR is one controller,
not the best possible one, so the numbers are a lower bound on what any controller could recover from.
Writes ``research/results/upright_basin_<task>.json`` (``..._<task>_brax_v1.json`` for ``--bodies brax_v1``).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from benchmarks._cli import add_bodies_flag, bodies_marker, bodies_suffix, paper_task
from lagrange.control import basin, linearise, lqr_gain, saturated_lqr
from lagrange.tasks import PAPER_TASKS
from optim.checkpoint import write_json

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
LEANS = (0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0)


def upright_lqr(task, r: float) -> np.ndarray:
    """The LQR gain ``K`` (m, 2n) of one control interval linearised at upright, for ``Q = diag(1 on q, 0.01 on qd)``
    and ``R = r I``: the gain of every research script's saturated LQR (:mod:`lagrange.control`)."""
    n, m = task.chain.n, task.chain.m
    A, B = linearise(task)
    return lqr_gain(A, B, np.diag([1.0] * n + [0.01] * n), r * np.eye(m))


def basin_row(task, r: float, steps: int) -> dict:
    A, B = linearise(task)
    K = upright_lqr(task, r)
    rho = float(np.max(np.abs(np.linalg.eigvals(A - B @ K))))
    b = basin(task, saturated_lqr(task, K), leans=LEANS, steps=steps)
    per_joint = {str(j): {"largest_recovered_lean": float(b.largest_recovered_lean[i]),
                          "every_lean_recovered": bool(b.recovered[i].all()),
                          "final_error": dict(zip(map(str, LEANS), b.final_error[i].tolist()))}
                 for i, j in enumerate(b.joints)}
    return {"r": r, "gain": K.tolist(), "closed_loop_spectral_radius": rho, "open_loop_spectral_radius":
            float(np.max(np.abs(np.linalg.eigvals(A)))), "joints": per_joint}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=tuple(PAPER_TASKS), default="acrobot")
    add_bodies_flag(p)
    p.add_argument("--r", nargs="+", type=float, default=[1.0, 1e2, 1e4],
                   help="LQR control weights R (larger: smaller gains)")
    p.add_argument("--steps", type=int, default=3000, help="control steps before a start is judged")
    p.add_argument("--out", default=None, help="result file (default research/results/upright_basin_<task>.json)")
    args = p.parse_args(argv)
    if args.steps < 1:
        raise SystemExit(f"--steps must be >= 1, got {args.steps}")
    if any(not r > 0 for r in args.r):
        raise SystemExit(f"--r must be > 0, got {args.r}")
    task = paper_task(args.task, args.bodies)
    rows = []
    for r in args.r:
        row = basin_row(task, r, args.steps)
        rows.append(row)
        leans = ", ".join(f"joint {j}: {v['largest_recovered_lean']} rad{' (all)' if v['every_lean_recovered'] else ''}"
                          for j, v in row["joints"].items())
        print(f"{args.task} R = {r:g}: closed-loop spectral radius {row['closed_loop_spectral_radius']:.4f}; "
              f"largest lean recovered from rest: {leans}", flush=True)
    out = {"task": args.task, **bodies_marker(args.bodies), "dt": task.dt,
           "gear": np.asarray(task.chain.gear).tolist(), "steps": args.steps, "leans": list(LEANS), "rows": rows}
    path = args.out or str(RESULTS / f"upright_basin_{args.task}{bodies_suffix(args.bodies)}.json")
    write_json(path, out)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
