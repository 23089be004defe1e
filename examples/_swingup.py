"""The command-line driver behind the swing-up examples: train with CE-APG, then write the artefacts.

Writes to ``--out``: ``checkpoint.eqx`` (equinox serialisation + JSON header, written atomically every
iteration), ``results.json``, ``learning_curve.png``, ``swingup.png`` and ``swingup.gif``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from typing import Callable

import matplotlib

matplotlib.use("Agg")

import jax  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks._files import write_json  # noqa: E402
from lagrange.plotting import episode_animation, episode_figure  # noqa: E402
from lagrange.tasks import BODIES, Task, balanced  # noqa: E402
from optim import ce_apg  # noqa: E402
from optim._loop import run  # noqa: E402
from optim.apg import config_to_dict, episode, evaluate  # noqa: E402
from optim.checkpoint import CheckpointError  # noqa: E402
from optim.devices import cpu_core_count, use_cpu_cores  # noqa: E402

EVAL_EPISODES = 16


def parse(description: str, default_out: str, argv=None, *, bodies: bool = True):
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
    return p.parse_args(argv)


def main(description: str, default_out: str, config: ce_apg.CEAPGConfig, quick: ce_apg.CEAPGConfig,
         task: Task | Callable[[], Task] | None = None, paper_return: float | None = None, argv=None) -> dict:
    """Parse the flags, train, evaluate and write the artefacts. ``task``: a Task, or a function that builds
    one (called after the CPU devices are set: building a chain runs JAX, which fixes the device count)."""
    args = parse(description, default_out, argv, bodies=task is None)
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


def learning_curve(history, path, cfg, paper_return):
    fig, ax = plt.subplots(figsize=(6, 4))
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
    ax.set_ylabel("fitness (mean of last batch returns)")
    ax.set_title(f"CE-APG on {cfg.task}")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
