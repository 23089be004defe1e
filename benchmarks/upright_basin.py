"""How far from upright can the task's torque limit still bring the chain back? Saturated LQR at the top.

    python -m benchmarks.upright_basin                   # the acrobot (seconds)
    python -m benchmarks.upright_basin --task double_cartpole
    python -m benchmarks.upright_basin --bodies brax_v1     # on the authors' Brax v1 bodies

The swing-up tasks end in a balance that "balanced" judges to 0.2 rad. This script asks how much of that
0.2 rad a simple stabilising controller can recover from with the task's own actuator limit. It linearises
``task.step`` (one control interval, RK4, by ``jax.jacfwd``) at the upright equilibrium, solves the discrete
LQR (``scipy.linalg.solve_discrete_are``) for ``Q = diag(1 on q, 0.01 on qd)`` and ``R = r``, and runs
``u = clip(-K dx, -1, 1)`` (``dx`` with wrapped angles) through the nonlinear ``task.step`` from a lean of
``d`` rad at one joint at a time (joint 1 leans the whole straight chain, a later joint bends it there),
starting at rest. A start "recovers" when, after ``--steps`` control steps, every coordinate is within 1e-3
(rad, m) and every velocity within 1e-3 of upright at rest. Reported: per joint, the largest ``d`` on the grid
up to which every start recovers (``every_lean_recovered``: the whole grid did); the closed-loop spectral radius of the linear model (< 1: stable); the gain.
A large ``r`` gives the smallest gains (least saturation); LQR is one controller, not the best possible one, so
the numbers are a lower bound on what any controller could recover from.
Writes ``benchmarks/results/upright_basin_<task>.json`` (``..._<task>_brax_v1.json`` for ``--bodies brax_v1``).
"""

from __future__ import annotations

import argparse
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from benchmarks._cli import add_bodies_flag, bodies_marker, bodies_suffix
from benchmarks._files import write_json
from lagrange.tasks import TASKS, TaskState, make_task, wrap

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
LEANS = (0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0)


def upright_state(task) -> np.ndarray:
    """``(q, qd)`` of the balanced chain at rest: the first pole's joint at pi, the rest (and any cart) at 0."""
    n = task.chain.n
    x = np.zeros(2 * n, np.asarray(task.chain.mass).dtype)  # the chain's float type
    x[task.first_pole] = np.pi
    return x


def linearise(task):
    """``(A, B)`` of one control interval at the upright equilibrium, ``x' = A x + B u``."""
    n = task.chain.n
    x0 = jnp.asarray(upright_state(task))

    def f(x, u):
        s = task.step(TaskState(x[:n], x[n:]), u)
        return jnp.concatenate([s.q, s.qd])

    u0 = jnp.zeros(task.chain.m, x0.dtype)
    return np.asarray(jax.jacfwd(f, 0)(x0, u0), np.float64), np.asarray(jax.jacfwd(f, 1)(x0, u0), np.float64)


def lqr_gain(A, B, r: float):
    n = A.shape[0] // 2
    Q = np.diag([1.0] * n + [0.01] * n)
    R = r * np.eye(B.shape[1])
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


def upright_deviation(task):
    """``deviation(q, qd) -> dx`` (..., 2n): the state minus upright at rest, angles wrapped (batched)."""
    n = task.chain.n
    x0 = jnp.asarray(upright_state(task))
    angular = jnp.arange(n) >= task.first_pole

    def deviation(q, qd):
        dq = jnp.where(angular, wrap(q - x0[:n]), q - x0[:n])
        return jnp.concatenate([dq, qd], axis=-1)

    return deviation


def saturated_lqr(task, K):
    """``controller(q, qd) -> u`` (..., m): the saturated LQR ``clip(-K dx, -1, 1)`` about upright (batched)."""
    deviation = upright_deviation(task)
    K = jnp.asarray(K, jnp.asarray(upright_state(task)).dtype)
    return lambda q, qd: jnp.clip(-(deviation(q, qd) @ K.T), -1.0, 1.0)


def make_rollout(task, K, steps: int):
    """``rollout(x)``: the largest |coordinate or velocity error| from upright at rest after ``steps`` control steps
    of the saturated LQR from ``x`` (NaN if the state went non-finite, which counts as not recovered), jitted."""
    n = task.chain.n
    dtype = jnp.asarray(upright_state(task)).dtype
    deviation, controller = upright_deviation(task), saturated_lqr(task, K)

    def body(x, _):
        s = task.step(TaskState(x[:n], x[n:]), controller(x[:n], x[n:]))
        return jnp.concatenate([s.q, s.qd]), None

    def rollout(x):
        xT, _ = jax.lax.scan(body, jnp.asarray(x, dtype), None, length=steps)
        return jnp.max(jnp.abs(deviation(xT[:n], xT[n:])))

    return jax.jit(rollout)


def basin(task, r: float, steps: int) -> dict:
    A, B = linearise(task)
    K = lqr_gain(A, B, r)
    rho = float(np.max(np.abs(np.linalg.eigvals(A - B @ K))))
    rollout = make_rollout(task, K, steps)
    x0 = upright_state(task)
    joints = range(task.first_pole, task.chain.n)
    per_joint = {}
    for j in joints:
        errors = []
        for d in LEANS:
            x = x0.copy()
            x[j] += d
            errors.append(float(rollout(jnp.asarray(x))))
        recovered = [e < 1e-3 for e in errors]
        largest = 0.0
        for d, ok in zip(LEANS, recovered):
            if not ok:
                break
            largest = d
        per_joint[str(j)] = {"largest_recovered_lean": largest, "every_lean_recovered": all(recovered),
                             "final_error": dict(zip(map(str, LEANS), errors))}
    return {"r": r, "gain": K.tolist(), "closed_loop_spectral_radius": rho, "open_loop_spectral_radius":
            float(np.max(np.abs(np.linalg.eigvals(A)))), "joints": per_joint}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=tuple(TASKS), default="acrobot")
    add_bodies_flag(p)
    p.add_argument("--r", nargs="+", type=float, default=[1.0, 1e2, 1e4],
                   help="LQR control weights R (larger: smaller gains)")
    p.add_argument("--steps", type=int, default=3000, help="control steps before a start is judged")
    p.add_argument("--out", default=None, help="result file (default benchmarks/results/upright_basin_<task>.json)")
    args = p.parse_args(argv)
    if args.steps < 1:
        raise SystemExit(f"--steps must be >= 1, got {args.steps}")
    if any(not r > 0 for r in args.r):
        raise SystemExit(f"--r must be > 0, got {args.r}")
    task = make_task(args.task, args.bodies)
    rows = []
    for r in args.r:
        row = basin(task, r, args.steps)
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
