"""The command-line driver of the locomotion examples: SHAC on DFlex's Hopper and Cheetah, its artefacts.

:func:`locomotion_main` parses the flags (``--seed --iterations --out --resume --overwrite --quick --no-progress
--eval-every``), trains SHAC with :func:`optim.train` (a progress bar and an atomic checkpoint every epoch;
``--resume`` continues it), evaluates the deterministic policy on 16 random starts every ``--eval-every`` epochs, and
writes to ``--out``:

- ``checkpoint.eqx``: the training state, what ``--resume`` reads;
- ``results.json``: ``return`` (the deterministic policy's mean undiscounted return over 16 episodes), its spread,
  the share of episodes that succeeded (``task.succeeded``), ``env_steps``, ``wall_clock_s`` (training, evaluations
  excluded) and ``total_s`` (the whole run), the learning curve, the seed and the config (strict JSON);
- ``learning_curve.png``: the evaluations' and the training episodes' returns against simulated steps and against
  wall-clock;
- ``gait.png`` and ``gait.gif``: one evaluation episode's gait.

A folder that holds a run is never overwritten by accident (:func:`optim.cli.prepare_run`).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from collections.abc import Callable

import jax
import numpy as np

from lagrange.compile import compiler_options
from lagrange.plotting import gait_animation, gait_figure
from lagrange.tasks import AbstractTask
from optim.checkpoint import CheckpointError
from optim.cli import EVAL_EPISODES, prepare_run, write_results
from optim.episode import episode
from optim.shac import SHACConfig
from optim.train import train
from policies import Actor

__all__ = ["locomotion_main", "learning_curves"]


def locomotion_main(description: str, default_out: str, make_task: Callable[[], AbstractTask], config: SHACConfig,
                    quick: SHACConfig, *, actor_units: tuple[int, ...] = (128, 64, 32), anchor: float | None = None,
                    argv: list[str] | None = None) -> dict:
    """Parse the flags, train SHAC with ``config`` (``quick`` with ``--quick``), evaluate, write the artefacts.

    Args:
        description: the ``--help`` text's first line.
        default_out: the default ``--out`` folder.
        make_task: builds the task (``Hopper.diffrl``).
        config: the SHAC config of a full run.
        quick: the config of ``--quick``.
        actor_units: the actor's hidden widths (the authors': 128, 64, 32).
        anchor: a published return to draw on the learning curve and keep in ``results.json``, or None.
        argv: the flags (default ``sys.argv[1:]``).

    Returns:
        The contents of ``results.json``.

    Raises:
        SystemExit: with a one-line message, before any training, for a bad flag, an ``--out`` that cannot be
            written or holds a run (without ``--resume`` or ``--overwrite``), a checkpoint that cannot be resumed.
    """
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of the run")
    p.add_argument("--iterations", "--epochs", type=int, default=None, help="epochs (default: the config's)")
    p.add_argument("--eval-every", type=int, default=None, help="evaluate every N epochs (default: 20 evaluations)")
    p.add_argument("--out", default=default_out, help="output folder")
    p.add_argument("--quick", action="store_true", help="a short demo run")
    p.add_argument("--resume", action="store_true", help="continue the run in OUT (its checkpoint.eqx)")
    p.add_argument("--overwrite", action="store_true", help="start afresh in an OUT that holds a run")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    cfg = quick if args.quick else config
    if args.iterations is not None:
        if args.iterations < 1:
            raise SystemExit(f"--iterations must be >= 1, got {args.iterations}")
        cfg = dataclasses.replace(cfg, iterations=args.iterations)
    eval_every = args.eval_every or max(1, cfg.iterations // 20)
    if eval_every < 1:
        raise SystemExit(f"--eval-every must be >= 1, got {args.eval_every}")
    ckpt = prepare_run(args.out, cfg, resume=args.resume, overwrite=args.overwrite,
                       iterations_given=args.iterations is not None, quick=args.quick)
    task = make_task()
    actor = Actor.for_task(task, units=actor_units)
    steps = cfg.iterations * cfg.env_steps_per_epoch()
    algorithm = "SHAC" if cfg.use_critic else "BPTT"
    print(f"{algorithm} on {task.name}: {cfg.iterations} epochs x {cfg.num_envs} envs x {cfg.short_horizon} steps = "
          f"{steps:.2e} env steps; writing to {args.out}")
    start = time.perf_counter()
    eval_key = jax.random.PRNGKey(10_000 + args.seed)
    try:
        run = train(cfg, task, actor, jax.random.PRNGKey(args.seed), checkpoint=ckpt, resume=args.resume,
                    seed=args.seed, progress=not args.no_progress, eval_every=eval_every,
                    eval_episodes=EVAL_EPISODES, eval_key=eval_key)
    except CheckpointError as err:
        raise SystemExit(f"error: cannot resume: {err}") from None
    except FloatingPointError as err:
        raise SystemExit(f"error: {err}") from None
    policy, norm = run.trainer.policy(run.state)
    play = jax.jit(lambda k: episode(task, policy, norm, k), compiler_options=compiler_options(task.chain))
    ep = play(eval_key)
    final, history = run.curve[-1], run.history
    results = {
        "task": task.name, "algorithm": algorithm, "return": final["return"], "return_std": final["return_std"],
        "succeeded_fraction": final["balanced"], "eval_episodes": EVAL_EPISODES,
        "untrained_return": run.curve[0]["return"], "env_steps": history[-1]["env_steps"] if history else 0.0,
        "epochs": cfg.iterations, "wall_clock_s": history[-1]["elapsed"] if history else 0.0,
        "total_s": time.perf_counter() - start, "example_episode_return": float(ep.ret),
        "example_episode_distance_m": float(ep.q[-1, 0] - ep.q[0, 0]), "anchor_return": anchor, "seed": args.seed,
        "curve": run.curve, "config": dataclasses.asdict(cfg),
    }
    results = write_results(os.path.join(args.out, "results.json"), results)
    episode_figures(task, ep, args.out, history=history, curve=run.curve,
                    title=f"{algorithm} on {task.name} (seed {args.seed})", anchor=anchor)
    print(f"return {results['return']:.0f} +- {results['return_std']:.0f} over {EVAL_EPISODES} episodes "
          f"(untrained {results['untrained_return']:.0f}); {results['env_steps']:.2e} env steps, "
          f"{results['wall_clock_s']:.0f} s training, {results['total_s']:.0f} s in all")
    return results


def episode_figures(task: AbstractTask, ep, out: str, *, history: list[dict], curve: list[dict], title: str,
                    anchor: float | None) -> None:
    """Write a run's ``learning_curve.png`` and its episode's ``gait.png`` and ``gait.gif`` to ``out``.

    Args:
        task: the locomotion task.
        ep: one deterministic episode of the policy (:func:`optim.episode.episode`).
        out: the folder.
        history: :attr:`optim.TrainResult.history`.
        curve: :attr:`optim.TrainResult.curve`.
        title: the learning curve's title.
        anchor: a published return to draw, or None.
    """
    learning_curves(history, curve, os.path.join(out, "learning_curve.png"), title=title, anchor=anchor)
    gait_figure(task, ep.q, ep.actions, os.path.join(out, "gait.png"), rewards=ep.rewards,
                title=f"{task.name}: return {float(ep.ret):.0f}, {float(ep.q[-1, 0] - ep.q[0, 0]):.1f} m")
    gait_animation(task, ep.q, os.path.join(out, "gait.gif"))


def learning_curves(history: list[dict], curve: list[dict], path: str, *, title: str,
                    anchor: float | None = None) -> None:
    """Draw a SHAC run's returns against simulated steps and against wall-clock (training time): the deterministic
    evaluations, the stochastic training episodes, and a published return as a dashed line.

    Args:
        history: :attr:`optim.TrainResult.history`.
        curve: :attr:`optim.TrainResult.curve`.
        path: the PNG file.
        title: the title.
        anchor: a published return, or None.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, key, label in ((axes[0], "env_steps", "simulated environment steps"),
                           (axes[1], "elapsed", "wall-clock, training [s]")):
        if history:
            ax.plot([h[key] for h in history], [h.get("episode_return", np.nan) for h in history], lw=0.8,
                    alpha=0.7, label="training episodes (stochastic)")
        if curve:
            ax.plot([c[key] for c in curve], [c["return"] for c in curve], "o-", label="deterministic evaluation")
        if anchor is not None:
            ax.axhline(anchor, color="k", ls="--", lw=1, label=f"published ({anchor:g})")
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    axes[0].set_ylabel("return")
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
