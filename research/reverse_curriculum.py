"""A reverse curriculum along a balanced swing-up: can CE-APG learn the double cartpole's swing-up from the hold back?

    python -m research.reverse_curriculum              # double cartpole, seed 0 (up to an hour on two cores)
    python -m research.reverse_curriculum --quick      # a smoke run of the same stages, tiny population
    python -m research.reverse_curriculum --task acrobot --bodies brax_v1   # along swingup_lqr_acrobot_brax_v1.json

CE-APG's double-cartpole policies spin (research/LOG.md); ``research/swingup_lqr.py`` found a balanced swing-up
worth 4396 (an open-loop swing-up caught by LQR). This script asks whether the learner can follow it backwards. The
states ``X[k] = (q, qd)`` at steps k of that controller's noise-free episode seed the training starts
(the task's ``starts``, with its +-0.01 noise). One CE-APG run (the laptop protocol's settings) goes through stages:

1. warm-up at the frontier ``--first`` (near the end of the swing-up): the horizons ``--horizons``, then the task's
   500 steps (a flat 500-step horizon does not learn the hold, ``research/balance_horizon.py``);
2. frontier stages: the frontier moves back by ``--move`` steps. A stage after which at least ``--held`` of 16
   episodes from the new frontier state balance moves the frontier there (and the move grows back to ``--move``);
   one after which they do not, but still do from the old frontier, is kept and the next try moves half as far (at
   least one step); one that lost both is rolled back (its training dropped; the retry draws new candidates) and the
   move halves; when it halves to 0 the next stage trains at the frontier itself (kept if that still holds) and moves
   of 1 are tried again. Until the first frontier holds, stages train on there. It stops at the hanging start or
   after ``--max-stages`` stages. The results file and the kept CE state are rewritten after every stage;
3. optionally ``--tail`` iterations on the task's own hanging starts (none by default: 20 of them lost the hold
   everywhere, upright included, in both runs that had them).

Every stage runs ``--per-stage`` CE iterations on ``X[lo:lo+10]`` (the frontier) repeated ``--frontier-weight`` times
plus every state from the frontier to ``--last`` (so the catch learnt earlier keeps being trained). The learning rate
is log-linear over the stages of a run without roll-backs (then ``lr_end``). After every stage the best candidate is
evaluated (16 deterministic episodes each) from the frontier state ``X[lo]`` (+-0.01), from upright, and from the 16
hanging starts of the paper tables. ``held_back_to`` is the last frontier kept. Writes
``research/results/reverse_curriculum_<task>.json`` (``..._<task>_brax_v1.json`` for ``--bodies brax_v1``, which
follows the Brax v1 bodies' controller, ``swingup_lqr_<task>_brax_v1.json``) and the final CE state to
``--checkpoint``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import time

import equinox as eqx
import jax
import jax.numpy as jnp

from benchmarks._cli import add_bodies_flag, bodies_marker, bodies_suffix, marked_bodies, paper_task
from optim import CEAPGConfig, checkpoint, evaluate
from optim.base import config_to_dict
from optim.checkpoint import write_json
from optim.devices import cpu_core_count, use_cpu_cores
from optim.train import describe
from research._apg import WIDTH, laptop_policy, laptop_task
from research._cli import at_least, repo_relative
from research.swingup_lqr import replay, results_path

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
EVAL_EPISODES = 16  # as benchmarks/paper_tables.py


def controller_states(task, controller: dict):
    """The states ``(H+1, 2n)`` (q then qd) of a ``swingup_lqr`` result's best controller, from the noise-free
    hanging start, and its return. Exits if the result was found on other bodies than ``task``'s."""
    found_on = marked_bodies(controller)
    if found_on != (task.bodies or "rods"):
        raise SystemExit(f"the swingup_lqr result was found on the {found_on!r} bodies, the "
                         f"task is on {task.bodies!r} (--bodies)")
    best = controller.get("best")
    if not best:
        raise SystemExit("the swingup_lqr result file holds no balanced controller ('best' is empty)")
    ret, states, _, _ = replay(task, controller["lqr_gain"], best)
    return jnp.concatenate([states.q, states.qd], axis=1), float(ret)


def warmup(first: int, horizons: list[int], per_stage: int, horizon: int):
    """The warm-up stages ``(frontier, training horizon, iterations)``: the shorter horizons at ``first``, then the full
    one there."""
    return [(first, h, per_stage) for h in horizons if h < horizon] + [(first, horizon, per_stage)]


def next_frontier(lo: int, move: int, held_new: bool, held_old: bool, full_move: int) -> tuple[int, int, bool]:
    """``(frontier, move, keep the stage's training)`` after a stage tried the frontier ``lo - move``. It held there:
    the frontier moves and the move grows back (doubling, at most ``full_move``). It did not, but still holds from the
    old frontier: the training is kept (it lost nothing) and the next try moves half as far, at least 1 step. It
    holds from neither: the stage is rolled back and the move halves (0: the next stage trains at the frontier itself,
    then moves of 1 are tried again)."""
    if held_new:
        return max(lo - move, 0), min(2 * move, full_move), True
    if held_old:
        return lo, max(move // 2, 1), True
    return lo, move // 2, False


_evaluate = eqx.filter_jit(evaluate)  # tasks, policies and keys as arguments: compiled once per kind of task


def evaluate_stage(task, X, frontier: int | None, previous: int | None, policy, norm, key) -> dict:
    """Balanced counts and mean returns of 16 deterministic episodes from the frontier state ``X[frontier]`` (+-0.01;
    hanging for None), from ``X[previous]`` when given, from the task's own (hanging) starts and from upright."""
    places = {"frontier": X[(frontier or 0):(frontier or 0) + 1], "hanging": None, "upright": None}
    if previous is not None:
        places["previous_frontier"] = X[previous:previous + 1]
    out = {}
    for name, starts in places.items():
        t = dataclasses.replace(task, upright=1.0) if name == "upright" else dataclasses.replace(task, starts=starts)
        ret, bal = _evaluate(t, policy, norm, key, EVAL_EPISODES)
        out[f"{name}_return"], out[f"{name}_balanced"] = float(jnp.mean(ret)), int(jnp.sum(bal))
    return out


def stage_starts(X, lo: int, last: int, frontier_weight: int):
    """Training starts of the stage at frontier ``lo``: ``X[lo:lo+10]`` repeated ``frontier_weight`` times, then
    ``X[lo:last]``."""
    return jnp.concatenate([jnp.tile(X[lo:lo + 10], (frontier_weight, 1)), X[lo:max(last, lo + 1)]])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=("double_cartpole", "acrobot"), default="double_cartpole")
    p.add_argument("--controller", default=None,
                   help="swingup_lqr result file (default research/results/swingup_lqr_<task>.json)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--first", type=int, default=120, help="the first frontier: a step of the controller's episode")
    p.add_argument("--last", type=int, default=200, help="training starts reach from the frontier to this step")
    p.add_argument("--move", type=int, default=5, help="steps the frontier moves back per stage")
    p.add_argument("--per-stage", type=int, default=6, help="CE iterations per stage")
    p.add_argument("--horizons", type=int, nargs="*", default=[100, 150, 200, 300, 400])
    p.add_argument("--frontier-weight", type=int, default=10)
    p.add_argument("--held", type=int, default=12,
                   help="episodes of 16 from the frontier state that must balance for a stage to be kept")
    p.add_argument("--max-stages", type=int, default=160, help="frontier stages tried at most (kept or rolled back)")
    p.add_argument("--tail", type=int, default=0,
                   help="CE iterations on the task's own hanging starts at the end (20 lost the hold in both runs)")
    p.add_argument("--lr-start", type=float, default=None, help="default: the laptop protocol's")
    p.add_argument("--cpu-devices", type=int, default=None, help="default: every core")
    p.add_argument("--quick", action="store_true",
                   help="4 candidates of 2 APG steps, frontier 130, at most 2 moves, one iteration each: a smoke run")
    p.add_argument("--checkpoint", default=None,
                   help="the final CE state (optim.load reads it with the task and policy; default "
                        "runs/reverse_curriculum/ce_apg_<task>_<seed>.eqx)")
    p.add_argument("--out", default=None,
                   help="result file (default research/results/reverse_curriculum_<task>.json)")
    add_bodies_flag(p)
    args = p.parse_args(argv)
    at_least(first=(args.first, 1), move=(args.move, 1), per_stage=(args.per_stage, 1), tail=(args.tail, 0),
             frontier_weight=(args.frontier_weight, 1), max_stages=(args.max_stages, 0), held=(args.held, 0))
    if args.held > EVAL_EPISODES:
        raise SystemExit(f"--held must be <= {EVAL_EPISODES}, got {args.held}")
    if args.last <= args.first:
        raise SystemExit(f"--last must be > --first ({args.first}), got {args.last}")
    use_cpu_cores(args.cpu_devices or cpu_core_count())
    task = paper_task(args.task, args.bodies)
    if args.last > task.horizon:
        raise SystemExit(f"--last must be <= the task's horizon {task.horizon}, got {args.last}")
    controller_path = results_path(args.task, args.controller, args.bodies)
    if not os.path.exists(controller_path):
        raise SystemExit(f"{controller_path} does not exist (--controller): run research/swingup_lqr.py --task "
                         f"{args.task} --bodies {args.bodies} first")
    with open(controller_path) as f:
        X, expert_return = controller_states(task, json.load(f))
    first, move, per_stage, horizons, tail, max_stages = (args.first, args.move, args.per_stage, args.horizons,
                                                           args.tail, args.max_stages)
    overrides = {} if args.lr_start is None else {"lr_start": args.lr_start}
    if args.quick:
        first, move, per_stage, horizons, tail, max_stages = 130, 130, 1, [100], 1, 2
        overrides.update(num_candidates=4, num_elites=2, apg_steps=2, episodes=1, fitness_window=1)
    warm = warmup(first, horizons, per_stage, task.horizon)
    planned = len(warm) * per_stage + -(-first // move) * per_stage + tail  # the learning-rate schedule's length
    cfg = CEAPGConfig.laptop(args.task, iterations=planned, **overrides)
    task = laptop_task(args.task, args.bodies)  # the observation the preset trains on (the acrobot's: sin, cos, dth)
    architecture = laptop_policy(args.task, task)  # the GRU the CE mean parameterises
    eval_key = jax.random.PRNGKey(10_000 + args.seed)  # the paper tables' evaluation starts
    print(f"{args.task}: controller return {expert_return:.1f}; the learning rate decays over {planned} iterations",
          flush=True)

    t0 = time.perf_counter()
    run = {"state": None, "env_steps": 0, "rows": []}

    def stage(lo, h, iterations, previous=None):
        """Train ``iterations`` CE iterations from frontier ``lo`` (None: the task's own starts), evaluate (also from
        the frontier ``previous``, when given), record."""
        train_task = task if lo is None else dataclasses.replace(
            task, starts=stage_starts(X, lo, args.last, args.frontier_weight))
        trainer = cfg.make_trainer(dataclasses.replace(train_task, horizon=h), architecture)
        state = run["state"] if run["state"] is not None else trainer.init(jax.random.PRNGKey(args.seed))
        for _ in range(iterations):
            state, metrics = trainer.update(state)
        run["env_steps"] += iterations * cfg.env_steps_per_iteration(h)
        policy, norm = trainer.policy(state)
        row = {"frontier": lo, "training_horizon": h, "iterations": int(state.iteration),
               "env_steps": run["env_steps"], "best_training_return": float(metrics["best_return"]),
               **evaluate_stage(task, X, lo, previous, policy, norm, eval_key), "seconds": time.perf_counter() - t0}
        print(f"frontier {'hanging (task)' if lo is None else lo}, horizon {h}: iteration {row['iterations']}, "
              f"best training return {row['best_training_return']:.0f}; balanced from the frontier "
              f"{row['frontier_balanced']}/16, upright {row['upright_balanced']}/16, "
              f"hanging {row['hanging_balanced']}/16 "
              f"(return {row['hanging_return']:.0f}); {row['seconds']:.0f} s", flush=True)
        run["rows"].append(row)
        return state, row

    suffix = bodies_suffix(args.bodies)
    path = args.out or str(RESULTS / f"reverse_curriculum_{args.task}{suffix}.json")
    ckpt = args.checkpoint or os.path.join("runs", "reverse_curriculum", f"ce_apg_{args.task}{suffix}_{args.seed}.eqx")
    os.makedirs(os.path.dirname(os.path.abspath(ckpt)), exist_ok=True)

    # the config as results have recorded it: the settings, and the task and policy they used to name
    record = {"task": args.task, **dataclasses.asdict(cfg), "horizon": task.horizon, "policy": "gru",
              "width": WIDTH[args.task], "trig_observation": args.task == "acrobot",  # as the laptop preset set it
              "bodies": args.bodies}

    def save(held, finished: bool) -> dict:
        """The results so far and the kept CE state, both written atomically after every stage."""
        rows = run["rows"]
        final = [r for r in rows if r.get("kept", True)][-1]  # the evaluation of the kept state
        out = {"task": args.task, **bodies_marker(args.bodies), "seed": args.seed,
               "controller": repo_relative(controller_path),
               "controller_return": expert_return,
               "first": first, "last": args.last, "move": move, "per_stage": per_stage, "horizons": horizons,
               "frontier_weight": args.frontier_weight, "tail": tail, "max_stages": max_stages, "held": args.held,
               "quick": args.quick, "config": record, "finished": finished, "held_back_to": held,
               "final_hanging_return": final["hanging_return"], "final_hanging_balanced": final["hanging_balanced"],
               "env_steps": run["env_steps"], "checkpoint": repo_relative(ckpt), "stages": rows}
        checkpoint.save(ckpt, run["state"], config=config_to_dict(cfg), identity=describe(task, architecture),
                        seed=args.seed, iteration=int(run["state"].iteration))
        write_json(path, out)
        return out

    def holds(row, where="frontier") -> bool:
        return row[f"{where}_balanced"] >= args.held

    for lo, h, iterations in warm:
        run["state"], row = stage(lo, h, iterations)
        save(None, False)
    held = first if holds(row) else None
    lo, step, attempts = first, move, 0
    while lo > 0 and attempts < max_stages:
        attempts += 1
        if held is None:  # the first frontier's hold not learnt yet: train on there (nothing to roll back to)
            run["state"], row = stage(first, task.horizon, per_stage)
            row["kept"] = True
            held = first if holds(row) else None
        else:
            if step == 0:  # consolidate at the frontier (kept if it still holds there), then try a move of 1 again
                state, row = stage(lo, task.horizon, per_stage)
                keep, step = holds(row), 1
            else:
                state, row = stage(max(lo - step, 0), task.horizon, per_stage, previous=lo)
                lo, step, keep = next_frontier(lo, step, holds(row), holds(row, "previous_frontier"), move)
                held = lo
            row["kept"] = keep
            if keep:
                run["state"] = state
            else:  # rolled back; the retry draws new candidates (the CE key folded with the attempt number)
                run["state"] = run["state"]._replace(key=jax.random.fold_in(run["state"].key, attempts))
        save(held, False)
    if tail:
        run["state"], _ = stage(None, task.horizon, tail)
    out = save(held, True)
    print(f"the catch held back to frontier {held}; from hanging {out['final_hanging_return']:.0f} "
          f"({out['final_hanging_balanced']}/16 balanced); wrote {path} and {ckpt}")
    return out


if __name__ == "__main__":
    main()
