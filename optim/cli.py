"""The command-line driver the swing-up examples use: flags, training, evaluation and the artefacts.

:func:`swingup_main` parses the flags (``--seed --iterations --out --resume --overwrite --quick --no-progress
--cpu-devices``, and ``--bodies`` where the example offers several body sets), trains with :func:`optim.train` (a
progress bar and an atomic checkpoint after every iteration; ``--resume`` continues it), evaluates the better of the
best candidate and the CE mean, and writes to ``--out``:

- ``checkpoint.eqx``: the training state with a JSON header (config, task and policy, seed, history), what ``--resume``
  reads;
- ``results.json``: the evaluation's return, balance, env steps, wall-clock, seed and config (strict JSON: a
  non-finite number is written as ``null``, and said so);
- ``learning_curve.png``: the fitness against simulated steps (:func:`learning_curve`);
- ``swingup.png``: one evaluation episode's angles, velocities and actuation (``lagrange.plotting``);
- ``swingup.gif``: the same episode, animated.

A new example is a config, its tasks and its policy, and one call:

```python
from lagrange.tasks import Cartpole
from optim import CEAPGConfig
from optim.cli import swingup_main
from policies import GRUPolicy

CONFIG = CEAPGConfig.laptop("cartpole")
swingup_main("Swing a cartpole up.", "runs/cartpole", CONFIG, CONFIG.with_iterations(8),
             tasks={"rods": Cartpole.rods, "brax_v1": Cartpole.brax_v1},
             policy=lambda task: GRUPolicy.for_task(task, width=16))
```

A folder that holds a run is never overwritten by accident: without ``--resume`` or ``--overwrite`` the driver refuses
to start there (:func:`prepare_run`); with ``--overwrite`` the old checkpoint stays until the new run has written its
first. Everything that can be checked before training (the flags, the folder) is checked before the first iteration.

The pictures are drawn on ``matplotlib.figure.Figure`` (no ``pyplot``): no backend is chosen, no window opened.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from typing import Any
from collections.abc import Callable

import jax
import numpy as np

from lagrange.plotting import episode_animation, episode_figure
from lagrange.tasks import AbstractTask, balanced
from optim.base import AlgorithmConfig, config_to_dict
from optim.checkpoint import CheckpointError, check_writable, read_header, strict_json, write_json
from optim.devices import cpu_core_count, use_cpu_cores
from optim.episode import episode, evaluate
from optim.train import train

__all__ = ["EVAL_EPISODES", "swingup_parser", "swingup_main", "prepare_run", "write_results", "learning_curve"]

EVAL_EPISODES = 16
"""Episodes (random starts) of the final evaluation, and of the selection between the best candidate and the mean."""


def swingup_parser(description: str, default_out: str, *, bodies: tuple[str, ...] = ()) -> argparse.ArgumentParser:
    """The examples' flags.

    Args:
        description: the ``--help`` text's first line.
        default_out: the default ``--out`` folder.
        bodies: the body sets ``--bodies`` offers (the first is the default) when there are several.
    """
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (training and evaluation starts)")
    p.add_argument("--iterations", type=int, default=None,
                   help="iterations (default: the config's; a CE-APG schedule and warm-up compress to fit)")
    p.add_argument("--out", default=default_out, help="output folder")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in OUT (its checkpoint.eqx) if there is one, with the flags it was started "
                        "with")
    p.add_argument("--overwrite", action="store_true",
                   help="start afresh in an OUT that holds a run; its checkpoint is replaced when the new run has "
                        "written its first (without --resume or --overwrite such an OUT is refused)")
    p.add_argument("--quick", action="store_true", help="a short demo run (about two minutes on two cores)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count(),
                   help="JAX CPU devices to shard the candidates over (default: one per core; 1 = a single device)")
    if len(bodies) > 1:  # a paper task; an example that brings its own chain has no such choice
        p.add_argument("--bodies", choices=bodies, default=bodies[0],
                       help="the body set: this library's rods, or the bodies the authors simulated in Brax v1")
    return p


def swingup_main(description: str, default_out: str, config: AlgorithmConfig, quick: AlgorithmConfig, *,
                 tasks: dict[str, Callable[[], AbstractTask]], policy: Callable[[AbstractTask], Any],
                 paper_return: float | None = None, argv: list[str] | None = None) -> dict:
    """Parse the flags, train ``config`` (``quick`` with ``--quick``), evaluate, write the artefacts to ``--out``.

    Args:
        description: the ``--help`` text's first line.
        default_out: the default ``--out`` folder.
        config: the algorithm's config of a full run.
        quick: the config of ``--quick``.
        tasks: the task's constructor per body set, e.g. ``{"rods": Acrobot.rods, "brax_v1": Acrobot.brax_v1}`` (the
            first is the default; ``--bodies`` chooses when there are several). They are called after the CPU
            devices are set, as is ``policy``.
        policy: ``policy(task)`` builds the policy module (its architecture; the algorithm draws its weights).
        paper_return: the paper's CE-APG return, drawn on the learning curve and kept in ``results.json``.
        argv: the flags (default ``sys.argv[1:]``).

    Returns:
        The contents of ``results.json``.

    Raises:
        SystemExit: with a one-line message, before any training, for a bad flag, an ``--out`` that cannot be
            written or that holds a run (without ``--resume`` or ``--overwrite``), and a checkpoint that cannot be
            resumed; after training, if the training state turned NaN.
    """
    if not tasks:
        raise ValueError("swingup_main: tasks must name at least one body set")
    args = swingup_parser(description, default_out, bodies=tuple(tasks)).parse_args(argv)
    if args.cpu_devices < 1:
        raise SystemExit(f"--cpu-devices must be >= 1, got {args.cpu_devices}")
    cfg = quick if args.quick else config
    if args.iterations is not None:
        if args.iterations < 1:
            raise SystemExit(f"--iterations must be >= 1, got {args.iterations}")
        # a CE-APG schedule and warm-up compress to fit
        cfg = cfg.with_iterations(args.iterations) if hasattr(cfg, "with_iterations") else dataclasses.replace(
            cfg, iterations=args.iterations)
    ckpt = prepare_run(args.out, cfg, resume=args.resume, overwrite=args.overwrite,
                       iterations_given=args.iterations is not None, quick=args.quick)
    use_cpu_cores(args.cpu_devices)  # before the first JAX computation
    bodies = getattr(args, "bodies", next(iter(tasks)))
    task = tasks[bodies]()
    pol = policy(task)
    steps = cfg.total_env_steps(task.horizon) if hasattr(cfg, "total_env_steps") else None
    print(f"{type(cfg).__name__.removesuffix('Config')} on {task.name} ({bodies}): {cfg.iterations} iterations"
          + (f", {steps:.2e} env steps" if steps else "") + f"; {len(jax.devices())} device(s); writing to {args.out}")
    try:
        result = train(cfg, task, pol, jax.random.PRNGKey(args.seed), checkpoint=ckpt, resume=args.resume,
                       seed=args.seed, progress=not args.no_progress)
    except CheckpointError as err:
        raise SystemExit(f"error: cannot resume: {err}") from None
    except FloatingPointError as err:
        raise SystemExit(f"error: {err}") from None
    state, history, trainer = result.state, result.history, result.trainer

    # Ship the better of the best candidate and the CE mean, chosen on selection episodes, then evaluate
    # both deterministically on other random starts (choosing on the reported episodes would flatter the choice).
    select_key, eval_key = jax.random.PRNGKey(20_000 + args.seed), jax.random.PRNGKey(10_000 + args.seed)
    evals, selection = {}, {}
    for which in ("best", "mean"):
        try:
            p, norm = trainer.policy(state, which)
        except ValueError:  # an algorithm without a search mean
            continue
        ev = jax.jit(lambda k: evaluate(task, p, norm, k, EVAL_EPISODES))
        selection[which] = float(np.mean(ev(select_key)[0]))
        rets, bal = ev(eval_key)
        evals[which] = (np.asarray(rets), np.asarray(bal), p, norm)
    which = max(selection, key=lambda w: selection[w] if np.isfinite(selection[w]) else -np.inf)
    rets, bal, p, norm = evals[which]
    ep = jax.jit(lambda k: episode(task, p, norm, k))(eval_key)
    results = {
        "task": task.name,
        "bodies": bodies,
        "horizon": task.horizon,
        "return": float(rets.mean()),
        "return_std": float(rets.std()),
        "balanced": bool(bal.all()),
        "balanced_fraction": float(bal.mean()),
        "eval_episodes": EVAL_EPISODES,
        "policy": which,
        "returns_by_policy": {w: float(v[0].mean()) for w, v in evals.items()},
        "selection_returns": selection,
        "example_episode_return": float(ep.ret),
        "example_episode_balanced": bool(balanced(task, ep.q)),
        "env_steps": history[-1]["env_steps"] if history else 0.0,
        "iterations": cfg.iterations,
        "wall_clock_seconds": history[-1]["elapsed"] if history else 0.0,
        "seed": args.seed,
        "devices": len(jax.devices()),
        "paper_return": paper_return,
        "config": config_to_dict(cfg),
    }
    write_results(os.path.join(args.out, "results.json"), results)
    learning_curve(history, result.curve, os.path.join(args.out, "learning_curve.png"),
                   title=f"{type(cfg).__name__.removesuffix('Config')} on {task.name}", paper_return=paper_return)
    title = f"{task.name}: return {float(ep.ret):.0f}, balanced {bool(balanced(task, ep.q))}"
    episode_figure(task, ep.q, ep.actions, os.path.join(args.out, "swingup.png"), qd=ep.qd, title=title)
    episode_animation(task, ep.q, os.path.join(args.out, "swingup.gif"))
    print(f"return {results['return']:.0f} +- {results['return_std']:.0f} over {EVAL_EPISODES} episodes "
          f"({which} policy), balanced in {results['balanced_fraction']:.0%}; "
          f"{results['env_steps']:.2e} env steps, {results['wall_clock_seconds']:.0f} s")
    return results


def prepare_run(out: str, config: AlgorithmConfig, *, resume: bool, overwrite: bool = False,
                iterations_given: bool = False, quick: bool | None = None) -> str:
    """Check the output folder of a run before any work, and return its checkpoint's path ``OUT/checkpoint.eqx``.

    Args:
        out: the ``--out`` folder (created if missing).
        config: the config the run will train.
        resume: ``--resume``: a checkpoint there is to be continued.
        overwrite: ``--overwrite``: a run there may be replaced (its checkpoint is, once the new run has written its
            first; its other files at the end).
        iterations_given: whether ``--iterations`` was given: only then may a resume change the checkpoint's
            iteration count (its learning-rate schedule spans the count, so the grown run mixes two schedules).
        quick: whether ``--quick`` was given (for the message), None where there is no such flag.

    Raises:
        SystemExit: with a one-line message when ``out`` is a file or cannot be written; when it holds a run
            (``checkpoint.eqx`` or ``results.json``) and neither ``resume`` nor ``overwrite`` is set; when both are;
            and on a resume whose checkpoint is unreadable or has another iteration count than ``config`` while
            ``iterations_given`` is false.
    """
    if resume and overwrite:
        raise SystemExit("error: --resume continues the run in --out and --overwrite replaces it: give one")
    if not str(out).strip():
        raise SystemExit("error: --out is empty; give the folder to write the run to")
    if os.path.exists(out) and not os.path.isdir(out):
        raise SystemExit(f"error: --out {out!r} is a file; give a folder")
    ckpt = os.path.join(out, "checkpoint.eqx")
    try:
        check_writable(ckpt, what="--out")
    except ValueError as err:
        raise SystemExit(f"error: {err}") from None
    results = os.path.join(out, "results.json")
    if not resume and not overwrite and (os.path.exists(ckpt) or os.path.exists(results)):
        held = ", ".join(os.path.basename(f) for f in (ckpt, results) if os.path.exists(f))
        raise SystemExit(f"error: --out {out!r} holds a run ({held}); --resume continues it, --overwrite replaces it, "
                         f"or give another --out")
    if resume and os.path.exists(ckpt):
        try:
            head = read_header(ckpt)
        except CheckpointError as err:
            raise SystemExit(f"error: cannot resume: {err}") from None
        saved = (head.get("config") or {}).get("iterations")
        if saved != config.iterations and not iterations_given:
            hint = {True: "without --quick if it was a full run", False: "with --quick if it was a quick run",
                    None: "with the flags it was started with"}[quick]
            raise SystemExit(
                f"error: cannot resume: {ckpt} is a run of {saved} iterations and these flags ask for "
                f"{config.iterations}, whose learning-rate schedule differs: resume it {hint}; to change its length "
                f"on a mixed schedule, pass --iterations {config.iterations} explicitly; or start afresh with "
                f"--overwrite")
    return ckpt


def write_results(path: str, results: dict) -> dict:
    """Write a run's results atomically as strict JSON: a non-finite number (a NaN return) becomes ``null``, and a
    warning on stderr names where.

    Args:
        path: the file (``results.json``).
        results: the results, a JSON-able dict.

    Returns:
        What was written.
    """
    clean = strict_json(results)
    nulls = sorted(_null_paths(results, clean))
    if nulls:
        print(f"warning: {', '.join(nulls)} not finite (NaN or infinite): written as null in {path}", file=sys.stderr)
    write_json(path, clean, indent=2, strict=True)  # atomically: a kill leaves the old file
    return clean


def _null_paths(raw, clean, prefix="") -> list[str]:
    if isinstance(raw, dict):
        return [p for k in raw for p in _null_paths(raw[k], clean[k], f"{prefix}{'.' if prefix else ''}{k}")]
    if isinstance(raw, (list, tuple)):
        return [p for i, (r, c) in enumerate(zip(raw, clean)) for p in _null_paths(r, c, f"{prefix}[{i}]")]
    return [prefix] if raw is not None and clean is None else []


def learning_curve(history: list[dict], curve: list[dict], path: str, *, title: str,
                   paper_return: float | None = None) -> None:
    """Draw a run against simulated steps: the fitness metrics the algorithm records (CE-APG's best candidate, elite
    mean and all finite candidates; SHAC's stochastic training episodes), the deterministic evaluations where there
    are any, and the paper's return as a dashed line.

    Args:
        history: :attr:`optim.TrainResult.history`.
        curve: :attr:`optim.TrainResult.curve`.
        path: the PNG file.
        title: the plot's title.
        paper_return: the paper's return, or None.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    steps = np.array([h["env_steps"] for h in history])
    keys = (("best_return", "best candidate"), ("elite_return", "elite mean"),
            ("mean_return", "all candidates (finite)"), ("episode_return", "training episodes (stochastic)"))
    shown = []
    for key, label in keys:
        if history and key in history[0]:
            ys = np.array([h[key] for h in history], dtype=float)
            ax.plot(steps, ys, lw=1 if key == "episode_return" else 1.5, label=label)
            if key != "mean_return":
                shown += [y for y in ys if np.isfinite(y)]
    if curve:
        ys = [c["return"] for c in curve]
        ax.plot([c["env_steps"] for c in curve], ys, "o-", label="deterministic evaluation")
        shown += ys
    # Scale to the best and elite curves: a few candidates that blow up (returns of -1e5 and less) would
    # otherwise flatten them; the all-candidates mean is then clipped at the bottom of the axes.
    if paper_return is not None:
        ax.axhline(paper_return, color="k", ls="--", lw=1, label=f"paper CE-APG ({paper_return:g})")
        shown.append(paper_return)
    if shown:
        lo, hi = min(shown), max(shown)
        pad = 0.05 * max(hi - lo, 1.0)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_xlabel("simulated environment steps")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))  # 1e5 steps and more: no overlapping labels
    ax.set_ylabel("return (fitness: mean of last batch returns)")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
