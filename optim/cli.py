"""The command-line driver the swing-up examples use: flags, training, evaluation and the artefacts.

:func:`swingup_main` parses the flags (``--seed --iterations --out --resume --quick --no-progress --cpu-devices``, and
``--bodies`` for a paper task), trains CE-APG with a progress bar and an atomic checkpoint after every iteration
(``--resume`` continues it), evaluates the better of the best candidate and the CE mean, and writes to ``--out``:

- ``checkpoint.eqx``: the training state with a JSON header (config, seed, history), what ``--resume`` reads;
- ``results.json``: the evaluation's return, balance, env steps, wall-clock, seed and config;
- ``learning_curve.png``: the best, elite and all-candidates fitness against simulated steps (:func:`learning_curve`);
- ``swingup.png``: one evaluation episode's angles, velocities and actuation (``lagrange.plotting``);
- ``swingup.gif``: the same episode, animated.

A new example is a config and one call:

```python
from optim.ce_apg import CEAPGConfig
from optim.cli import swingup_main

CONFIG = CEAPGConfig.laptop("cartpole")
swingup_main("Swing a cartpole up.", "runs/cartpole", CONFIG, CONFIG.with_iterations(8))
```

:func:`shac_learning_curve` draws the SHAC example's curve. The pictures are drawn on ``matplotlib.figure.Figure``
(no ``pyplot``): no backend is chosen, no window opened.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from typing import Callable

import jax
import numpy as np

from lagrange.plotting import episode_animation, episode_figure
from lagrange.tasks import BODIES, Task, balanced
from optim import ce_apg, run
from optim.apg import config_to_dict, episode, evaluate
from optim.checkpoint import CheckpointError, write_json
from optim.devices import cpu_core_count, use_cpu_cores

__all__ = ["EVAL_EPISODES", "swingup_parser", "swingup_main", "learning_curve", "shac_learning_curve"]

EVAL_EPISODES = 16
"""Episodes (random starts) of the final evaluation, and of the selection between the best candidate and the mean."""


def swingup_parser(description: str, default_out: str, *, bodies: bool = True) -> argparse.ArgumentParser:
    """The examples' flags; ``bodies=False`` for an example that brings its own chain (no ``--bodies``)."""
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (training and evaluation starts)")
    p.add_argument("--iterations", type=int, default=None,
                   help="CE iterations (default: the config's; its learning-rate schedule and warm-up compress to fit)")
    p.add_argument("--out", default=default_out, help="output folder")
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.eqx if it exists")
    p.add_argument("--quick", action="store_true", help="a short demo run (about two minutes on two cores)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count(),
                   help="JAX CPU devices to shard the candidates over (default: one per core; 1 = a single device)")
    if bodies:  # a paper task; an example that brings its own chain has no such choice
        p.add_argument("--bodies", choices=BODIES, default="rods",
                       help="the chain: this library's rods, or the bodies the authors simulated in Brax v1")
    return p


def swingup_main(description: str, default_out: str, config: ce_apg.CEAPGConfig, quick: ce_apg.CEAPGConfig, *,
                 task: Task | Callable[[], Task] | None = None, paper_return: float | None = None,
                 argv: list[str] | None = None) -> dict:
    """Parse the flags (``argv``, default ``sys.argv[1:]``), train ``config`` (``quick`` with ``--quick``), evaluate,
    write the artefacts to ``--out`` and return the contents of ``results.json``.

    ``task``: None for the config's paper task (then ``--bodies`` is offered), a Task, or a function that builds one
    (called after the CPU devices are set: building a chain runs JAX, which fixes the device count).
    ``paper_return``: the paper's CE-APG return, drawn on the learning curve and kept in ``results.json``.
    Bad flags and a checkpoint that cannot be resumed exit with a one-line message (``SystemExit``)."""
    args = swingup_parser(description, default_out, bodies=task is None).parse_args(argv)
    if args.cpu_devices < 1:
        raise SystemExit(f"--cpu-devices must be >= 1, got {args.cpu_devices}")
    cfg = quick if args.quick else config
    if getattr(args, "bodies", "rods") != cfg.bodies:
        cfg = dataclasses.replace(cfg, bodies=args.bodies)
    if args.iterations is not None:
        if args.iterations < 1:
            raise SystemExit(f"--iterations must be >= 1, got {args.iterations}")
        cfg = cfg.with_iterations(args.iterations)  # the learning-rate schedule and any warm-up compress to fit
    use_cpu_cores(args.cpu_devices)  # before the first JAX computation
    os.makedirs(args.out, exist_ok=True)
    if callable(task) and not isinstance(task, Task):
        task = task()
    trainer = ce_apg.make_trainer(cfg, task)
    task = trainer.task
    ckpt = os.path.join(args.out, "checkpoint.eqx")
    if not args.resume and os.path.exists(ckpt):
        os.remove(ckpt)
    on = cfg.task if cfg.bodies == "rods" else f"{cfg.task} ({cfg.bodies} bodies)"
    print(f"CE-APG on {on}: {cfg.iterations} iterations, {cfg.total_env_steps():.2e} env steps; "
          f"{len(jax.devices())} device(s); writing to {args.out}")
    try:
        state, history = run(trainer, jax.random.PRNGKey(args.seed), iterations=cfg.iterations, ckpt_path=ckpt,
                             resume=args.resume, progress=not args.no_progress, seed=args.seed)
    except CheckpointError as err:
        raise SystemExit(f"error: cannot resume: {err}") from None

    # Ship the better of the best candidate and the CE mean, chosen on selection episodes, then evaluate
    # both deterministically on other random starts (choosing on the reported episodes would flatter the choice).
    select_key, eval_key = jax.random.PRNGKey(20_000 + args.seed), jax.random.PRNGKey(10_000 + args.seed)
    evals, selection = {}, {}
    for which in ("best", "mean"):
        policy, norm = trainer.policy(state, which)
        ev = jax.jit(lambda k: evaluate(task, policy, norm, k, EVAL_EPISODES))
        selection[which] = float(np.mean(ev(select_key)[0]))
        rets, bal = ev(eval_key)
        evals[which] = (np.asarray(rets), np.asarray(bal), policy, norm)
    which = max(selection, key=selection.get)
    rets, bal, policy, norm = evals[which]
    ep = jax.jit(lambda k: episode(task, policy, norm, k))(eval_key)
    results = {
        "task": cfg.task,
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
    write_json(os.path.join(args.out, "results.json"), results, indent=2)  # atomically: a kill leaves the old file
    learning_curve(history, os.path.join(args.out, "learning_curve.png"), cfg, paper_return)
    title = f"{task.kind}: return {float(ep.ret):.0f}, balanced {bool(balanced(task, ep.q))}"
    episode_figure(task, ep.q, ep.actions, os.path.join(args.out, "swingup.png"), qd=ep.qd, title=title)
    episode_animation(task, ep.q, os.path.join(args.out, "swingup.gif"))
    print(f"return {results['return']:.0f} +- {results['return_std']:.0f} over {EVAL_EPISODES} episodes "
          f"({which} policy), balanced in {results['balanced_fraction']:.0%}; "
          f"{results['env_steps']:.2e} env steps, {results['wall_clock_seconds']:.0f} s")
    return results


def learning_curve(history: list[dict], path: str, cfg, paper_return: float | None = None) -> None:
    """Draw a CE-APG run's ``history`` (from :func:`optim.run`) to ``path`` (PNG): the best candidate's, the elites'
    and all finite candidates' fitness against simulated steps, and ``paper_return`` as a dashed line."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    steps = np.array([h["env_steps"] for h in history])
    for key, label in (("best_return", "best candidate"), ("elite_return", "elite mean"),
                       ("mean_return", "all candidates (finite)")):
        if history and key in history[0]:
            ax.plot(steps, [h[key] for h in history], label=label)
    # Scale to the best and elite curves: a few candidates that blow up (returns of -1e5 and less) would
    # otherwise flatten them; the all-candidates mean is then clipped at the bottom of the axes.
    shown = [h[k] for h in history for k in ("best_return", "elite_return") if np.isfinite(h.get(k, np.nan))]
    if paper_return is not None:
        ax.axhline(paper_return, color="k", ls="--", lw=1, label=f"paper CE-APG ({paper_return:g})")
        shown.append(paper_return)
    if shown:
        lo, hi = min(shown), max(shown)
        pad = 0.05 * max(hi - lo, 1.0)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_xlabel("simulated environment steps")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))  # 1e5 steps and more: no overlapping labels
    ax.set_ylabel("fitness (mean of last batch returns)")
    ax.set_title(f"CE-APG on {cfg.task}")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def shac_learning_curve(history: list[dict], curve: list[dict], path: str, *, title: str) -> None:
    """Draw a SHAC run (``history, curve`` from :func:`optim.shac.run`) to ``path`` (PNG): the deterministic
    evaluations' return and the stochastic training episodes' return against simulated steps."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.plot([c["env_steps"] for c in curve], [c["return"] for c in curve], "o-", label="deterministic evaluation")
    train = [(h["env_steps"], h["episode_return"]) for h in history if h["episodes"] > 0]
    if train:
        ax.plot(*np.array(train).T, lw=1, alpha=0.6, label="training episodes (stochastic)")
    ax.set_xlabel("simulated environment steps")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))  # 1e5 steps and more: no overlapping labels
    ax.set_ylabel("episode return")
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
