"""How the trained cartpole policy holds the pole: the cart's drift and the force's chattering.

    python examples/cartpole_swingup.py --out runs/cartpole_swingup        # the example's default run (about 90 s)
    python -m research.cartpole_hold --checkpoint runs/cartpole_swingup/checkpoint.eqx

Loads the example's checkpoint (its task and policy read from the header; checkpoints of the format before issue 30
are refused), runs ``--policy`` (the CE mean or the best candidate; by default the one the
example reports, named under ``policy`` in the ``results.json`` beside the checkpoint, else the mean) from the 16
evaluation starts of ``benchmarks/paper_tables.py`` for seed 0 (key 10_000), and prints the mean return, the range
of the cart's final position, and, after ``--from-step``, the fraction of control steps at which the force changes
sign, its mean and largest magnitude (in units of the 100 N gear) and the pole's largest distance from upright.
"""

import argparse
import json
import os

import jax
import numpy as np

from lagrange.tasks import upright_error
from optim import episode
from research._cli import load_run


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="runs/cartpole_swingup/checkpoint.eqx")
    p.add_argument("--policy", choices=("mean", "best"), default=None,
                   help="default: results.json's 'policy' beside the checkpoint, else mean")
    p.add_argument("--from-step", type=int, default=200)
    args = p.parse_args(argv)
    if args.policy is None:
        results = os.path.join(os.path.dirname(args.checkpoint), "results.json")
        args.policy = "mean"
        if os.path.exists(results):
            with open(results) as f:
                args.policy = json.load(f).get("policy", "mean")
    trainer, state = load_run(args.checkpoint)  # the task and policy rebuilt from the checkpoint's header
    policy, norm = trainer.policy(state, args.policy)
    keys = jax.random.split(jax.random.PRNGKey(10_000), 16)
    eps = jax.jit(jax.vmap(lambda k: episode(trainer.task, policy, norm, k)))(keys)
    x = np.asarray(eps.q[:, -1, 0])
    a = np.asarray(eps.actions[:, args.from_step:, 0])
    flips = np.mean(np.sign(a[:, 1:]) != np.sign(a[:, :-1]))
    th = np.asarray(upright_error(trainer.task, eps.q[:, args.from_step:]))
    print(f"{args.policy} policy: return {float(np.mean(eps.ret)):.1f}; final cart x {x.min():.1f} to {x.max():.1f} m; "
          f"after step {args.from_step}: force changes sign at {flips:.0%} of steps, mean |a| {np.abs(a).mean():.2g} "
          f"(max {np.abs(a).max():.2g}), pole within {th.max():.3f} rad of upright")


if __name__ == "__main__":
    main()
