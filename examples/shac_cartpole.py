"""Train SHAC on the SHAC authors' cartpole swing-up, with their hyperparameters.

    python examples/shac_cartpole.py            # the authors' 500 epochs x 64 envs x 32 steps (about 1e6 steps)
    python examples/shac_cartpole.py --quick    # 150 epochs x 32 envs, a short demo

Writes ``results.json`` (deterministic return of the final policy over 16 random starts, the fraction
that balance, env steps, wall-clock, the config) and ``learning_curve.png`` (deterministic evaluation
return and the stochastic training episodes' return against simulated steps) to ``--out``.
"""

import argparse
import dataclasses
import os

import jax

from optim import shac
from optim.checkpoint import write_json
from optim.cli import shac_learning_curve

QUICK = dict(num_envs=32, epochs=150)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of the run")
    p.add_argument("--epochs", type=int, default=None, help="epochs (default: the config's)")
    p.add_argument("--eval-every", type=int, default=25, help="evaluate the deterministic policy every N epochs")
    p.add_argument("--out", default="runs/shac_cartpole", help="output folder")
    p.add_argument("--quick", action="store_true", help=f"a short demo run ({QUICK})")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)

    cfg = shac.SHACConfig(task="shac_cartpole", **(QUICK if args.quick else {}))
    if args.epochs is not None:
        if args.epochs < 1:
            raise SystemExit(f"--epochs must be >= 1, got {args.epochs}")
        cfg = dataclasses.replace(cfg, epochs=args.epochs)
    os.makedirs(args.out, exist_ok=True)
    trainer = shac.make_trainer(cfg)
    print(f"SHAC on {cfg.task}: {cfg.epochs} epochs x {cfg.num_envs} envs x {cfg.short_horizon} steps "
          f"= {cfg.epochs * cfg.env_steps_per_epoch():.2e} env steps; writing to {args.out}")
    state, history, curve = shac.run(trainer, jax.random.PRNGKey(args.seed), eval_every=args.eval_every,
                                     eval_key=jax.random.PRNGKey(10_000 + args.seed),
                                     progress=not args.no_progress)
    final = curve[-1]
    results = {
        "task": cfg.task,
        "algorithm": "SHAC",
        "return": final["return"],
        "return_std": final["return_std"],
        "balanced_fraction": final["balanced"],
        "eval_episodes": 16,
        "untrained_return": curve[0]["return"],
        "env_steps": history[-1]["env_steps"],
        "epochs": cfg.epochs,
        "wall_clock_seconds": history[-1]["elapsed"],
        "seed": args.seed,
        "curve": curve,
        "config": dataclasses.asdict(cfg),
    }
    write_json(os.path.join(args.out, "results.json"), results, indent=2)  # atomically: a kill leaves the old file
    shac_learning_curve(history, curve, os.path.join(args.out, "learning_curve.png"),
                        title=f"SHAC on the authors' cartpole swing-up (seed {args.seed})")
    print(f"return {final['return']:.1f} +- {final['return_std']:.1f} over 16 episodes (untrained "
          f"{curve[0]['return']:.0f}), balanced in {final['balanced']:.0%}; {results['env_steps']:.2e} env steps, "
          f"{results['wall_clock_seconds']:.0f} s")
    return results


if __name__ == "__main__":
    main()
