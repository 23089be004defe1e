"""How far is a learnt swing-up from its local optimum? Per-start refinement of a CE-APG policy's episodes.

    python -m research.refine_swingup        # the curriculum acrobot runs (paper_tables --variant warmup), seeds 3 5 7
    python -m research.refine_swingup --runs runs/paper_tables/laptop_ep1 --seeds 5

CE-APG's acrobot policies settle at returns of about 2840-3000 (the paper's mean is 3053) and hold the arm up
loosely. This script asks whether that is the learner or the motion: it loads a final policy (a checkpoint of
``benchmarks/paper_tables.py``; its task and policy are read from the header, and checkpoints of the format before
issue 30 are refused) and, for each of the 16 evaluation starts of the paper tables, adds a free
time-varying offset to the policy's action, ``a_t = tanh(atanh(pi(o_t, h_t)) + z_t)``, the policy's feedback kept,
and maximises that episode's return over ``z`` (T x m) by Adam through ``task.step`` (``z = 0`` is the policy's own
episode up to the round-off of ``tanh(atanh(a))``, which the chaotic swing-up may amplify: both returns are reported).
The result is what a controller that starts as this policy can reach *from this start* nearby: a local optimum around
the learnt swing-up, not a global bound (another swing-up could be better). The best ``z`` seen is kept, so the refined
return is never below that of ``z = 0``. Reports per seed the policy's and the refined returns, how many episodes are
``balanced`` before and after, and the refined episodes' *arrival* (the first step from which every link stays within
0.2 rad of upright to the end) with the penalty ``10 T - return`` spent before and after it. Writes
``research/results/refine_swingup_<runs folder>.json``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.tasks import balanced, upright_error
from optim import episode
from optim.checkpoint import write_json
from optim.devices import cpu_core_count, use_cpu_cores
from research._ascent import adam_best_seen
from research._cli import add_checkpoint_flags, at_least, load_run, paper_tables_checkpoint, runs_result_path

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
EVAL_EPISODES = 16  # as benchmarks/paper_tables.py


def rollout(task, policy, norm, s0, z):
    """The policy's episode from ``s0`` with the action offset ``z`` (T, m): ``(return, rewards (T,), q (T+1, n))``."""
    def body(carry, x):
        s, h = carry
        t, zt = x
        o = task.observe(s)
        a, h = policy(o if norm is None else norm(o), h, t == 0)
        a = jnp.tanh(jnp.arctanh(jnp.clip(a, -1 + 1e-6, 1 - 1e-6)) + zt)
        s2 = task.step(s, a)
        return (s2, h), (task.reward(s, a, s2), s2.q)

    _, (r, q) = jax.lax.scan(body, (s0, policy.initial_state()), (jnp.arange(z.shape[0]), z))
    return r.sum(), r, jnp.concatenate([s0.q[None], q])


def refine(task, policy, norm, starts, *, steps: int, learning_rate: float):
    """Adam (cosine-decayed ``learning_rate`` -> 1 %) on each start's offset;
    ``(best z, best return, start return)``."""
    z0 = jnp.zeros((len(starts.q), task.horizon, task.action_size), starts.q.dtype)

    def one_start(z, s0):
        return adam_best_seen(lambda z: rollout(task, policy, norm, s0, z)[0], z, steps=steps,
                              learning_rate=learning_rate)

    return jax.jit(jax.vmap(one_start))(z0, starts)


def arrival(task, q, tolerance: float = 0.2):
    """Per episode, the first step from which every link stays within ``tolerance`` of upright (None: never)."""
    up = np.asarray(upright_error(task, q)) <= tolerance  # (episodes, T+1)
    out = []
    for row in up:
        bad = np.nonzero(~row)[0]
        out.append(0 if bad.size == 0 else (int(bad[-1]) + 1 if bad[-1] + 1 < row.size else None))
    return out


def one(path: str, seed: int, steps: int, learning_rate: float) -> dict:
    trainer, state = load_run(path)  # the task and policy rebuilt from the checkpoint's header
    policy, norm = trainer.policy(state)
    task = trainer.task
    keys = jax.random.split(jax.random.PRNGKey(10_000 + seed), EVAL_EPISODES)  # paper_tables' evaluation starts
    starts = jax.vmap(task.reset)(keys)
    t0 = time.perf_counter()
    z, best, ret0 = jax.block_until_ready(refine(task, policy, norm, starts, steps=steps, learning_rate=learning_rate))
    seconds = time.perf_counter() - t0
    ret, rewards, q = jax.vmap(lambda s, z: rollout(task, policy, norm, s, z))(starts, z)
    own = jax.jit(jax.vmap(lambda k: episode(task, policy, norm, k)))(keys)  # the policy's own episodes
    arrive = arrival(task, q)
    rewards = np.asarray(rewards)
    before = [float(10 * a - rewards[i, :a].sum()) if a is not None else None for i, a in enumerate(arrive)]
    after = [float(10 * (task.horizon - a) - rewards[i, a:].sum()) if a is not None else None
             for i, a in enumerate(arrive)]
    return {
        "seed": seed, "checkpoint": path, "steps": steps, "learning_rate": learning_rate, "seconds": seconds,
        "policy_returns": [float(x) for x in own.ret],
        "policy_balanced": [bool(b) for b in np.asarray(balanced(task, own.q))],
        "zero_offset_returns": [float(x) for x in ret0],
        "refined_returns": [float(x) for x in ret],
        "refined_best_seen": [float(x) for x in best],
        "refined_balanced": [bool(b) for b in np.asarray(balanced(task, q))],
        "arrival_step": arrive, "penalty_before_arrival": before, "penalty_after_arrival": after,
        "max_abs_offset": float(jnp.max(jnp.abs(z))),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_checkpoint_flags(p, runs="runs/paper_tables/laptop_warmup", seeds=[3, 5, 7])
    p.add_argument("--steps", type=int, default=3000, help="Adam steps per start")
    p.add_argument("--lr", type=float, default=1e-2, help="Adam's initial step on the offsets (cosine-decayed to 1 %%)")
    p.add_argument("--out", default=None, help="result file (default research/results/refine_swingup_<runs>.json)")
    args = p.parse_args(argv)
    at_least(steps=(args.steps, 0), cpu_devices=(args.cpu_devices, 1))
    if not args.lr > 0:
        raise SystemExit(f"--lr must be > 0, got {args.lr}")
    use_cpu_cores(min(args.cpu_devices, cpu_core_count()))
    rows = []
    for seed in args.seeds:
        path = paper_tables_checkpoint(args.runs, args.task, seed)
        r = one(path, seed, args.steps, args.lr)
        arr = [a for a in r["arrival_step"] if a is not None]
        print(f"seed {seed}: policy {np.mean(r['policy_returns']):.1f} ({sum(r['policy_balanced'])} of "
              f"{EVAL_EPISODES} balanced) -> refined {np.mean(r['refined_returns']):.1f} (per start "
              f"{min(r['refined_returns']):.0f}..{max(r['refined_returns']):.0f}; {sum(r['refined_balanced'])} of "
              f"{EVAL_EPISODES} balanced); arrival at steps {min(arr) if arr else '-'}..{max(arr) if arr else '-'}; "
              f"{r['seconds']:.0f} s", flush=True)
        rows.append(r)
    out = {"runs": args.runs, "task": args.task, "episodes": EVAL_EPISODES, "rows": rows}
    path = runs_result_path(args.out, RESULTS, "refine_swingup", args.runs)
    write_json(path, out)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
