"""Three changes to CE-APG on the balance-only acrobot, none of which teaches it to hold the arm up.

    python -m benchmarks.experiments.acrobot_balance_patches --patch none --seed 0        # about 2 minutes each
    python -m benchmarks.experiments.acrobot_balance_patches --patch terminal --seed 0
    python -m benchmarks.experiments.acrobot_balance_patches --patch select1000 --seed 0
    python -m benchmarks.experiments.acrobot_balance_patches --patch none --curriculum --seed 0   # 100 -> ... -> 500
    python -m benchmarks.experiments.acrobot_balance_patches --patch unwrapped --curriculum --seed 0

The setting is ``benchmarks.balance_horizon``'s (rods unless ``--bodies``; every training episode starts upright;
the laptop protocol for 60 iterations): 100-step training episodes, or with ``--curriculum`` its curriculum 100 -> 150
-> 200 -> 300 -> 400 -> 500 (10 iterations each). The patch replaces ``optim.ce_apg``'s APG steps
(``benchmarks.experiments._apg``):

- ``none``: unchanged (the library's loss and fitness);
- ``terminal``: the APG loss adds ``10 log(sum th^2 + 0.1 sum dth^2)`` at each training episode's last state (wrapped
  angles, 0 = upright; the batch mean); the fitness stays the return;
- ``select1000``: the fitness is the mean return of two forward 1000-step episodes from upright with the candidate's
  post-APG parameters instead of its last batch returns (the gradient unchanged);
- ``unwrapped``: the training reward (gradient and fitness) is the paper's with *unwrapped* angles,
  ``10 - sum (q - offset)^2 - 0.01 sum dq^2``, so a full turn costs ``(2 pi)^2`` per step instead of nothing.

Evaluation is the paper's task from 16 upright starts (key ``10_000 + seed``, as ``balance_horizon``) over 500 steps:
printed are the best policy's mean return and the episodes balanced.
"""

import argparse
import dataclasses
import json
import time

import jax
import jax.numpy as jnp

import optim.ce_apg as ce_apg
from benchmarks.balance_horizon import config, evaluate
from benchmarks.experiments._apg import apg_steps_with, paper_objective
from optim._loop import run
from lagrange.tasks import wrap
from optim.apg import episode

PATCHES = ("none", "terminal", "select1000", "unwrapped")
CURRICULUM = (100, 150, 200, 300, 400)


def _offset(n):
    return jnp.zeros(n).at[0].set(jnp.pi)  # first pole: 0 = hanging in q, upright at pi


def terminal_objective(task, eps):
    q, qd = eps.q[:, -1, task.first_pole:], eps.qd[:, -1, task.first_pole:]  # each episode's last state
    th = wrap(q - _offset(q.shape[-1]))  # as Task.angles
    penalty = 10 * jnp.log(jnp.sum(th**2, -1) + 0.1 * jnp.sum(qd**2, -1))
    ret = jnp.mean(eps.ret)
    return -ret + jnp.mean(penalty), ret


def unwrapped_objective(task, eps):
    q, qd = eps.q[:, 1:, task.first_pole:], eps.qd[:, 1:, task.first_pole:]  # the rewards' next states
    r = 10.0 - jnp.sum((q - _offset(q.shape[-1])) ** 2, -1) - 0.01 * jnp.sum(qd**2, -1)
    ret = jnp.mean(jnp.sum(r, -1))
    return -ret, ret


def select_by_forward(horizon: int = 1000, episodes: int = 2):
    base = apg_steps_with(paper_objective)

    def apg_steps(task, unravel, params, normalizer, key, **kw):
        res = base(task, unravel, params, normalizer, key, **kw)
        long = dataclasses.replace(task, horizon=horizon)
        keys = jax.random.split(jax.random.fold_in(key, 1_000_003), episodes)
        ret = jnp.mean(jax.vmap(lambda k: episode(long, unravel(res.params), res.normalizer, k).ret)(keys))
        return res._replace(returns=jnp.full_like(res.returns, ret), finite=res.finite & jnp.isfinite(ret))

    return apg_steps


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--patch", choices=PATCHES, default="none")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--curriculum", action="store_true", help="100 -> 150 -> 200 -> 300 -> 400 -> 500 steps")
    p.add_argument("--iterations", type=int, default=60)
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    args = p.parse_args(argv)
    if args.patch == "terminal":
        ce_apg.apg_steps = apg_steps_with(terminal_objective)
    elif args.patch == "unwrapped":
        ce_apg.apg_steps = apg_steps_with(unwrapped_objective)
    elif args.patch == "select1000":
        ce_apg.apg_steps = select_by_forward()
    cfg = (config("acrobot", 500, args.iterations, CURRICULUM, args.bodies) if args.curriculum
           else config("acrobot", 100, args.iterations, (), args.bodies))
    trainer = ce_apg.make_trainer(cfg)
    t0 = time.perf_counter()
    state, history = run(trainer, jax.random.PRNGKey(args.seed), iterations=cfg.iterations, progress=False,
                         seed=args.seed)
    policy, norm = trainer.policy(state)
    up = dataclasses.replace(trainer.task, upright=1.0, horizon=500)
    out = {"patch": args.patch, "curriculum": args.curriculum, "seed": args.seed, "bodies": args.bodies,
           "iterations": cfg.iterations, "seconds": round(time.perf_counter() - t0),
           "best_candidate_return": float(history[-1]["best_return"]),
           **evaluate(up, policy, norm, jax.random.PRNGKey(10_000 + args.seed))}
    out["balanced_of_16"] = round(out["balanced_fraction"] * 16)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
