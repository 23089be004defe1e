"""Train SHAC on the SHAC authors' cartpole swing-up (NVlabs/DiffRL's), with their hyperparameters.

    python examples/shac_cartpole.py            # the authors' 500 epochs x 64 envs x 32 steps (about 1e6 steps)
    python examples/shac_cartpole.py --quick    # 150 epochs x 32 envs, a short demo
    python examples/shac_cartpole.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (deterministic return of the final policy over 16 random starts, the
fraction that balance, env steps, wall-clock, the config) and ``learning_curve.png`` (deterministic evaluation return
and the stochastic training episodes' return against simulated steps) to ``--out``.
"""

import argparse
import dataclasses
import os

import jax

import optim
from lagrange.tasks import DiffRLCartpole
from optim.checkpoint import CheckpointError
from optim.cli import learning_curve, prepare_run, write_results
from policies import Actor

CONFIG = optim.SHACConfig()  # the authors' cartpole swing-up settings
QUICK = dataclasses.replace(CONFIG, num_envs=32, iterations=150)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of the run")
    p.add_argument("--iterations", "--epochs", type=int, default=None, help="epochs (default: the config's)")
    p.add_argument("--eval-every", type=int, default=25, help="evaluate the deterministic policy every N epochs")
    p.add_argument("--out", default="runs/shac_cartpole", help="output folder")
    p.add_argument("--quick", action="store_true", help="a short demo run (150 epochs x 32 envs)")
    p.add_argument("--resume", action="store_true", help="continue the run in OUT (its checkpoint.eqx)")
    p.add_argument("--overwrite", action="store_true", help="start afresh in an OUT that holds a run")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)

    if args.eval_every < 1:
        raise SystemExit(f"--eval-every must be >= 1, got {args.eval_every}")
    cfg = QUICK if args.quick else CONFIG
    if args.iterations is not None:
        if args.iterations < 1:
            raise SystemExit(f"--iterations must be >= 1, got {args.iterations}")
        cfg = dataclasses.replace(cfg, iterations=args.iterations)
    ckpt = prepare_run(args.out, cfg, resume=args.resume, overwrite=args.overwrite,
                       iterations_given=args.iterations is not None, quick=args.quick)  # refuses to lose a run
    task = DiffRLCartpole.diffrl()
    actor = Actor.for_task(task, units=(64, 64), init_log_std=-1.0)  # the authors' actor
    print(f"SHAC on {task.name}: {cfg.iterations} epochs x {cfg.num_envs} envs x {cfg.short_horizon} steps "
          f"= {cfg.iterations * cfg.env_steps_per_epoch():.2e} env steps; writing to {args.out}")
    try:
        run = optim.train(cfg, task, actor, jax.random.PRNGKey(args.seed), checkpoint=ckpt, resume=args.resume,
                          seed=args.seed, progress=not args.no_progress, eval_every=args.eval_every,
                          eval_key=jax.random.PRNGKey(10_000 + args.seed))
    except CheckpointError as err:
        raise SystemExit(f"error: cannot resume: {err}") from None
    final, history = run.curve[-1], run.history
    results = {"task": task.name, "algorithm": "SHAC", "return": final["return"], "return_std": final["return_std"],
               "balanced_fraction": final["balanced"], "eval_episodes": 16, "untrained_return": run.curve[0]["return"],
               "env_steps": history[-1]["env_steps"], "epochs": cfg.iterations,
               "wall_clock_seconds": history[-1]["elapsed"], "seed": args.seed, "curve": run.curve,
               "config": dataclasses.asdict(cfg)}
    results = write_results(os.path.join(args.out, "results.json"), results)  # strict JSON, atomically
    learning_curve(history, run.curve, os.path.join(args.out, "learning_curve.png"),
                   title=f"SHAC on the authors' cartpole swing-up (seed {args.seed})")
    print(f"return {final['return']:.1f} +- {final['return_std']:.1f} over 16 episodes (untrained "
          f"{run.curve[0]['return']:.0f}), balanced in {final['balanced']:.0%}; {results['env_steps']:.2e} env steps, "
          f"{results['wall_clock_seconds']:.0f} s")
    return results


if __name__ == "__main__":
    main()
