"""Can BPTT learn to *balance*? CE-APG on the balance-only task at several episode lengths.

    python -m research.balance_horizon                      # double cartpole, H = 100 ... 500 and a curriculum
                                                            # (about 15 minutes on one device)
    python -m research.balance_horizon --task acrobot       # the same question for the acrobot
    python -m research.balance_horizon --quick              # two horizons, 5 iterations: a pipeline check
    python -m research.balance_horizon --task acrobot --bodies brax_v1   # on the authors' Brax v1 bodies

The swing-up tasks end in a balance, so a learner that cannot learn the balance from upright cannot
learn the swing-up either. This script takes the swing-up out: every training episode starts balanced
upright (``CEAPGConfig.upright_starts = 1``) and lasts ``H`` control steps, and CE-APG runs its laptop
protocol for ``--iterations`` iterations at each ``H``; a last run spends the same iterations on a
curriculum (``CEAPGConfig.warmup_horizons``): equal stages at each shorter ``H`` in turn, then 500. The final policy is
then evaluated on 16 upright starts twice: over ``H`` steps (what it was trained on) and over the paper's 500 steps
(what the task asks). "balanced" is the task's definition (every link within 0.2 rad of upright over the final 20 % of
the episode), on the evaluation's own length. For a cart task the cart's mean ``|x|`` at step 500 shows drift. Writes
``research/results/balance_horizon_<task>.json`` (``..._<task>_brax_v1.json`` for ``--bodies brax_v1``).
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import time

import jax
import numpy as np

from benchmarks._cli import add_bodies_flag, bodies_marker, bodies_suffix
from lagrange.tasks import balanced
from optim import CEAPGConfig, episode, train
from optim.checkpoint import write_json
from optim.devices import cpu_core_count, use_cpu_cores
from research._apg import laptop_policy, laptop_task

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
HORIZONS = {False: [100, 150, 200, 300, 400, 500], True: [50, 100]}
EVAL_EPISODES = 16


def results_path(task_name: str, bodies: str = "rods") -> pathlib.Path:
    """``research/results/balance_horizon_<task>.json``, ``..._<task>_<bodies>.json`` for bodies other than the
    rods."""
    return RESULTS / f"balance_horizon_{task_name}{bodies_suffix(bodies)}.json"


def evaluate(task, policy, norm, key):
    eps = jax.vmap(lambda k: episode(task, policy, norm, k))(jax.random.split(key, EVAL_EPISODES))
    out = {"return": float(np.mean(eps.ret)), "balanced_fraction": float(np.mean(balanced(task, eps.q)))}
    if task.cart:
        out["mean_abs_final_x"] = float(np.mean(np.abs(eps.q[:, -1, 0])))
    return out


def setup(task_name: str, horizon: int, iterations: int, warmup: tuple[int, ...] = (), bodies: str = "rods"):
    """``(config, task, policy)``: the task's laptop protocol (:func:`research._apg.laptop_task`, ``laptop_policy``)
    on upright starts only, ``horizon``-step episodes, the warm-up ``warmup`` (from upright, equal shares of the
    iterations) or none (replacing any warm-up a preset has), on ``bodies``."""
    warm = dict(warmup_horizons=warmup, warmup_iterations=iterations // (len(warmup) + 1), warmup_upright=1.0)
    cfg = CEAPGConfig.laptop(task_name, upright_starts=1.0, iterations=iterations, **warm)
    task = laptop_task(task_name, bodies, horizon=horizon)
    return cfg, task, laptop_policy(task_name, task)


def one(task_name: str, horizon: int, iterations: int, seed: int, warmup: tuple[int, ...] = (),
        bodies: str = "rods") -> dict:
    cfg, task, policy = setup(task_name, horizon, iterations, warmup, bodies)
    t0 = time.perf_counter()
    result = train(cfg, task, policy, jax.random.PRNGKey(seed), progress=False, seed=seed)
    seconds = time.perf_counter() - t0
    trainer, history = result.trainer, result.history
    policy, norm = trainer.policy(result.state)
    up = dataclasses.replace(trainer.task, upright=1.0)
    key = jax.random.PRNGKey(10_000 + seed)
    return {
        "horizon": horizon,
        "warmup_horizons": list(warmup),
        "at_training_horizon": evaluate(up, policy, norm, key),
        "at_500": evaluate(dataclasses.replace(up, horizon=500), policy, norm, key),
        "best_candidate_curve": [float(h["best_return"]) for h in history],
        "env_steps": history[-1]["env_steps"],
        "seconds": seconds,
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=("double_cartpole", "acrobot", "cartpole"), default="double_cartpole")
    p.add_argument("--iterations", type=int, default=60)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count())
    add_bodies_flag(p)
    args = p.parse_args(argv)
    use_cpu_cores(args.cpu_devices)
    iterations = 5 if args.quick else args.iterations
    rows = []
    runs = [(h, ()) for h in HORIZONS[args.quick]]
    # the curriculum: the same budget of iterations, the horizon growing in equal stages up to the last one
    runs.append((HORIZONS[args.quick][-1], tuple(HORIZONS[args.quick][:-1])))
    for h, warmup in runs:
        r = one(args.task, h, iterations, args.seed, warmup, args.bodies)
        rows.append(r)
        a, b = r["at_training_horizon"], r["at_500"]
        drift = f", final |x| {b['mean_abs_final_x']:.2f} m" if "mean_abs_final_x" in b else ""
        name = f"H = {h:3d}" if not warmup else f"H = {' -> '.join(map(str, warmup + (h,)))}"
        print(f"{name}: over H {a['return']:7.0f} of {10 * h} ({a['balanced_fraction']:.0%} balanced); "
              f"over 500 {b['return']:9.0f} ({b['balanced_fraction']:.0%} balanced{drift}); "
              f"{r['env_steps']:.1e} env steps, {r['seconds']:.0f} s", flush=True)
    out = {"task": args.task, **bodies_marker(args.bodies), "seed": args.seed, "iterations": iterations,
           "devices": len(jax.devices()),
           "config": "CEAPGConfig.laptop(task, upright_starts=1, iterations) on the task with horizon=H", "rows": rows}
    if not args.quick:
        path = results_path(args.task, args.bodies)
        write_json(path, out)
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
