"""Does SHAC's critic-bootstrapped short-horizon gradient learn the acrobot's upright hold that CE-APG's BPTT does not?

    python -m research.shac_acrobot_hold --bodies rods --seed 0
    python -m research.shac_acrobot_hold --bodies brax_v1 --seed 0

SHAC (the authors' hyperparameters, ``SHACConfig`` defaults: 64 envs x 32-step windows, 500 epochs (its
``iterations``), about 1e6 env steps; their actor, ``policies.Actor`` of units (64, 64) and initial log-std -1) on the
balance-only acrobot (every episode starts upright with the task's +-0.01 noise, 500 steps). The final deterministic
actor is then run from 16 upright starts for ``--steps`` control steps; printed: its return over the first 500, the
episodes balanced (the task's test on those 500 steps) and, per episode, the first step at which a link is more than
0.5 rad from upright (None: never within ``--steps``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import jax
import numpy as np

from benchmarks._cli import paper_task
from lagrange.tasks import balanced
from optim import SHACConfig, episode, train
from policies import Actor
from research.hold_duration import leave_steps


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bodies", default="rods", choices=["rods", "brax_v1"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--epochs", type=int, default=500)
    p.add_argument("--steps", type=int, default=2000, help="control steps of the hold test")
    p.add_argument("--upright", type=float, default=1.0, help="probability a training episode starts upright")
    args = p.parse_args(argv)

    task = paper_task("acrobot", args.bodies)
    train_task = dataclasses.replace(task, upright=args.upright)
    cfg = SHACConfig(iterations=args.epochs)
    actor = Actor.for_task(train_task, units=(64, 64), init_log_std=-1.0)  # the authors' actor
    result = train(cfg, train_task, actor, jax.random.PRNGKey(args.seed), eval_every=50,
                   eval_key=jax.random.PRNGKey(10_000 + args.seed))
    history, curve, trainer = result.history, result.curve, result.trainer
    pol, norm = trainer.policy(result.state)
    keys = jax.random.split(jax.random.PRNGKey(20_000 + args.seed), 16)
    up = dataclasses.replace(task, upright=1.0)
    eps = jax.jit(jax.vmap(lambda k: episode(up, pol, norm, k)))(keys)
    long = jax.jit(jax.vmap(lambda k: episode(dataclasses.replace(up, horizon=args.steps), pol, norm, k)))(keys)
    hang = jax.jit(jax.vmap(lambda k: episode(task, pol, norm, k)))(keys)
    out = {
        "bodies": args.bodies, "seed": args.seed, "epochs": args.epochs, "upright": args.upright,
        "env_steps": history[-1]["env_steps"], "seconds": history[-1]["elapsed"],
        "curve": [(c["iteration"], round(c["return"], 1), c["balanced"]) for c in curve],
        "upright_return": float(np.mean(eps.ret)), "upright_balanced": int(np.sum(balanced(up, eps.q))),
        "leaves_upright_0.5": leave_steps(up, np.asarray(long.q), tolerance=0.5, from_step=0),
        "hanging_return": float(np.mean(hang.ret)), "hanging_balanced": int(np.sum(balanced(task, hang.q))),
    }
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
