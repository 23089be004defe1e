"""How long does a trained swing-up policy hold the chain up? Its final policy run past the episode's end.

    python -m research.hold_duration                                  # the acrobot runs of paper_tables --variant ep1
    python -m research.hold_duration --runs runs/paper_tables/laptop_ep1h600 --seeds 0 4

CE-APG trains on episodes of a fixed length (the task's 500 steps) and is judged by a hold over their last 20 %. This
script loads the final checkpoints ``RUNS/ce_apg_<task>_<seed>.eqx`` written by ``benchmarks/paper_tables.py`` (their
configs, tasks and policies are read from the checkpoints' headers; checkpoints of the format before issue 30 are
refused, the runs behind the recorded numbers have to be trained again with the current script), runs the final
deterministic policy from the same 16 hanging starts as the paper-tables evaluation for ``--steps`` control steps
instead of the task's horizon (the first ``horizon`` steps are that evaluation's episodes: their returns are checked
against it), and reports, per episode, the first step at or after ``--from-step`` at which some link is more than
``--tolerance`` rad from upright ("leaves upright"; none if it never does). Writes
``research/results/hold_duration_<runs folder name>.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib

import jax
import numpy as np

from lagrange.tasks import balanced, leaves_upright
from optim import episode
from optim.checkpoint import write_json
from optim.devices import cpu_core_count, use_cpu_cores
from research._cli import add_checkpoint_flags, at_least, load_run, paper_tables_checkpoint, runs_result_path

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
EVAL_EPISODES = 16  # as benchmarks/paper_tables.py


def leave_steps(task, q, *, tolerance: float, from_step: int) -> list:
    """Per episode of ``q`` (episodes, T, n), the first step >= ``from_step`` at which some link is more than
    ``tolerance`` rad from upright (:func:`lagrange.tasks.leaves_upright`), or None where it never is."""
    return [int(t) if t >= 0 else None for t in leaves_upright(task, q, tolerance=tolerance, from_step=from_step)]


def one(path: str, seed: int, steps: int, tolerance: float, from_step: int) -> dict:
    trainer, state = load_run(path)  # the task and policy rebuilt from the checkpoint's header
    policy, norm = trainer.policy(state)
    task = trainer.task
    long = dataclasses.replace(task, horizon=steps)
    keys = jax.random.split(jax.random.PRNGKey(10_000 + seed), EVAL_EPISODES)  # paper_tables' evaluation starts
    eps = jax.jit(jax.vmap(lambda k: episode(long, policy, norm, k)))(keys)
    q = np.asarray(eps.q)
    own = jax.jit(jax.vmap(lambda k: episode(task, policy, norm, k)))(keys)  # the task's own episodes
    own_q = np.asarray(own.q)
    prefix = float(np.max(np.abs(q[:, :own_q.shape[1]] - own_q)))  # the long run starts as the task's episode
    leave = leave_steps(task, q, tolerance=tolerance, from_step=from_step)
    return {
        "seed": seed, "checkpoint": path, "iteration": int(state.iteration), "horizon": task.horizon,
        "return": float(np.mean(own.ret)),
        "balanced": [bool(b) for b in np.asarray(balanced(task, own.q))],
        "prefix_max_abs_difference": prefix,
        "leaves_upright_at": leave,
        "still_up_at_end": sum(x is None for x in leave),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_checkpoint_flags(p, runs="runs/paper_tables/laptop_ep1", seeds=list(range(8)))
    p.add_argument("--steps", type=int, default=2000, help="control steps to run each policy for")
    p.add_argument("--tolerance", type=float, default=0.5, help="rad from upright that counts as having left it")
    p.add_argument("--from-step", type=int, default=400, help="first step at which leaving upright is looked for")
    p.add_argument("--out", default=None, help="result file (default research/results/hold_duration_<runs>.json)")
    args = p.parse_args(argv)
    at_least(steps=(args.steps, 1), from_step=(args.from_step, 0), cpu_devices=(args.cpu_devices, 1))
    if not args.tolerance > 0:
        raise SystemExit(f"--tolerance must be > 0, got {args.tolerance}")
    use_cpu_cores(min(args.cpu_devices, cpu_core_count()))
    rows = []
    for seed in args.seeds:
        path = paper_tables_checkpoint(args.runs, args.task, seed)
        r = one(path, seed, args.steps, args.tolerance, args.from_step)
        left = [x for x in r["leaves_upright_at"] if x is not None]
        print(f"seed {seed}: return {r['return']:.0f}, {sum(r['balanced'])} of {EVAL_EPISODES} balanced; leaves "
              f"{args.tolerance} rad at steps {min(left) if left else '-'}..{max(left) if left else '-'}, "
              f"{r['still_up_at_end']} of {EVAL_EPISODES} still up at step {args.steps}; first {r['horizon']} steps "
              f"differ from the task's episodes by {r['prefix_max_abs_difference']:.1e} rad", flush=True)
        rows.append(r)
    out = {"runs": args.runs, "task": args.task, "steps": args.steps, "tolerance": args.tolerance,
           "from_step": args.from_step, "episodes": EVAL_EPISODES, "rows": rows}
    path = runs_result_path(args.out, RESULTS, "hold_duration", args.runs)
    write_json(path, out)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
