"""CE-APG variants for ``examples/custom_chain.py``: does any of them balance the chain?

    python -m research.custom_chain_variants NAME [--seed 0]   # 2-5 minutes each on one CPU device
    python -m research.custom_chain_variants --list

Each variant is the example's ``CONFIG`` with the overrides in ``VARIANTS``. Every 10 iterations it prints the best
candidate's training return (over that iteration's training episodes: upright ones included, warm-up stages on
their own horizons) and the best candidate's return over the example's 16 evaluation episodes (hanging starts, the
evaluation key ``10_000 + seed``) with how many of them are ``balanced``.
"""

import argparse
import dataclasses
import os
import sys
import time

import jax
import jax.numpy as jnp

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))

import custom_chain  # noqa: E402

from optim import evaluate  # noqa: E402
from policies import GRUPolicy  # noqa: E402

BALANCE_FIRST = dict(warmup_upright=1.0)
VARIANTS = {
    "longer": dict(iterations=80),
    "upright25": dict(iterations=80, upright_starts=0.25),
    "upright50": dict(iterations=80, upright_starts=0.5),
    "hanging_curriculum": dict(iterations=60, warmup_horizons=(100, 150, 200), warmup_iterations=10,
                               warmup_upright=0.0),
    "balance_curriculum": dict(iterations=80, warmup_horizons=(50, 100, 150), warmup_iterations=10,
                               upright_starts=0.25, **BALANCE_FIRST),
    "balance_curriculum_long_stages": dict(iterations=80, warmup_horizons=(100, 250), warmup_iterations=15,
                                           **BALANCE_FIRST),
    "balance_curriculum_to_250": dict(iterations=100, warmup_horizons=(50, 100, 150, 200, 250), warmup_iterations=12,
                                      upright_starts=0.25, **BALANCE_FIRST),
    "balance_only_truncated25": dict(iterations=40, upright_starts=1.0, truncation=25),
    "balance_only_truncated50": dict(iterations=40, upright_starts=1.0, truncation=50),
}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name", nargs="?", choices=sorted(VARIANTS))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--list", action="store_true", help="print the variants and their overrides")
    args = p.parse_args(argv)
    if args.list or args.name is None:
        for name, over in VARIANTS.items():
            print(f"{name}: {over}")
        return
    cfg = dataclasses.replace(custom_chain.CONFIG, **VARIANTS[args.name])
    task = custom_chain.make_task()
    trainer = cfg.make_trainer(task, GRUPolicy.for_task(task, width=16))  # the example's policy
    state = trainer.init(jax.random.PRNGKey(args.seed))
    key = jax.random.PRNGKey(10_000 + args.seed)
    scores = jax.jit(lambda policy, norm: evaluate(trainer.task, policy, norm, key, 16))
    t0 = time.time()
    for it in range(cfg.iterations):
        state, metrics = trainer.update(state)
        if (it + 1) % 10 == 0 or it + 1 == cfg.iterations:
            returns, balanced = scores(*trainer.policy(state))
            print(f"{args.name} seed {args.seed} iteration {it + 1}: best training return "
                  f"{float(metrics['best_return']):.0f}, evaluation {float(jnp.mean(returns)):.0f}, balanced "
                  f"{int(balanced.sum())} of 16, non-finite {int(metrics['nonfinite'])}, {time.time() - t0:.0f} s",
                  flush=True)


if __name__ == "__main__":
    main()
