"""Levers beyond fidelity on the swing-ups' laptop protocol: do they leave the spinning optimum (double cartpole) or
tighten the hold (acrobot)?

    python -m research.swingup_levers --task double_cartpole --lever clip --seeds 0 1 2 3
    python -m research.swingup_levers --task double_cartpole --lever vel --seeds 0 1 2 3
    python -m research.swingup_levers --task acrobot --lever clip --seeds 0 1 2 3

Each run is ``CEAPGConfig.laptop(task)`` (the examples' protocol; the acrobot observes ``(sin, cos)``) on the rods
(``--bodies brax_v1`` for the authors' bodies) with one change:

- ``none``: unchanged (the published Table I runs, for a same-machine comparison);
- ``clip``: every APG step's gradient rescaled to global norm 1 before Adam (``max_grad_norm=1.0``). BPTT gradients
  of a 500-step swing-up have norms of 1e6-1e10 with spikes of 10-200 times a candidate's median
  (``research.apg_gradient_norms``); Adam's second moment keeps a spike for the rest of a 25-100 step run and so
  shrinks every later step. With every gradient cut to norm 1, Adam sees directions only;
- ``vel``: the APG loss and the fitness use the reward with a velocity weight of ``--vel-weight`` (0.1) instead of the
  paper's 0.01, ``10 - sum th^2 - w sum dth^2``: a pole whirling at 5 rad/s then pays ~2.5 per step per pole instead
  of ~0.25, so spinning is no longer worth ~6.7 of the 10 per step, while a hold (no motion) is worth the same. The
  evaluation keeps the paper's reward;
- ``clipvel``: both;
- ``velsched``: the velocity weight of ``vel`` on a schedule over the run, ``--vel-stages`` (0.1, 0.03, 0.01) for
  equal shares of the iterations, ending at the paper's 0.01: first learn to swing up without whirling, then to do it
  fast (one trainer per stage, ``CEAPGConfig.make_trainer(objective=...)``, carrying the state; the learning-rate
  schedule runs across all stages; no checkpoints);
- ``tip`` (double cartpole only): the APG loss and the fitness use the reward the paper's appendix (X-C) describes
  and the authors' Brax fork's ``inverted_double_pendulum_swingup`` (at commit 4858be6) computes, an alive bonus minus
  the second pole's tip's distance from a goal above the cart, ``10 - (0.05 x_tip^2 + (z_tip - 2)^2) - (0.01 dth1^2
  + 0.005 dth2^2)``, with the tip ``(x_tip, z_tip)`` of the state before the step and the velocities after it, as
  there. It is smooth in the angles (no wrap), and a whirling first pole pays for its tip's swing below the cart.
  The evaluation keeps the library's reward (``DoubleCartpole``'s, the paper-facts'), and records the tip return too.

Evaluation as ``benchmarks/paper_tables.py``: the final best candidate, deterministic, on 16 starts from
``PRNGKey(10_000 + seed)``, with the paper's reward; the run's last best-candidate fitness is recorded too (the
paper's statistic; for ``vel`` it is in the shaped reward). Checkpoints under ``runs/swingup_levers/`` resume.
Appends to ``research/results/swingup_levers.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.plotting import chain_outline  # noqa: E402
from optim import CEAPGConfig, episode, evaluate, train
from optim.checkpoint import write_json
from optim.devices import use_cpu_cores
from optim.base import config_to_dict
from optim.checkpoint import save
from optim.train import TrainResult, describe
from research._apg import iterate, laptop_policy, laptop_task
from research._cli import REPO

LEVERS = ("none", "clip", "vel", "clipvel", "velsched", "tip")
EVAL_EPISODES = 16
PAPER_VELOCITY_WEIGHT = 0.01


def velocity_objective(task, weight: float):
    """Minus the mean return under ``10 - sum th^2 - weight sum dth^2``: the paper's rewards plus the extra velocity
    penalty ``(weight - 0.01) sum dth^2`` of every next state (the reward is computed on the next state)."""
    extra_weight = weight - PAPER_VELOCITY_WEIGHT

    def objective(episodes):
        dth = episodes.qd[:, 1:, task.first_pole:]  # (batch, T, links): the next states' pole velocities
        shaped = episodes.ret - extra_weight * jnp.sum(dth**2, axis=(1, 2))
        return -jnp.mean(shaped)

    return objective


def tip_rewards(task, q, qd):
    """The fork's tip reward of every step ``(..., T)`` from an episode's ``q, qd`` of shape ``(..., T + 1, n)``."""
    tip = chain_outline(task.chain, q[..., :-1, :])[..., -1, :]  # (..., T, 2): (x, z) before each step
    dth = qd[..., 1:, task.first_pole:]
    return 10.0 - (0.05 * tip[..., 0] ** 2 + (tip[..., 1] - 2.0) ** 2) - (0.01 * dth[..., 0] ** 2
                                                                            + 0.005 * dth[..., 1] ** 2)


def tip_objective(task):
    """Minus the mean return under :func:`tip_rewards`."""

    def objective(episodes):
        return -jnp.mean(jnp.sum(tip_rewards(task, episodes.q, episodes.qd), axis=-1))

    return objective


def staged(config: CEAPGConfig, task, policy, seed: int, weights, path: str) -> TrainResult:
    """CE-APG with the velocity weight ``weights[i]`` over the ``i``-th equal share of ``config.iterations``; the final
    state is saved to ``path`` as ``optim.train`` would (``optim.load`` reads it; it does not resume)."""
    bounds = np.linspace(0, config.iterations, len(weights) + 1).round().astype(int)
    trainers = [config.make_trainer(task, policy, objective=velocity_objective(task, w)) for w in weights]
    state, history, t0 = trainers[0].init(jax.random.PRNGKey(seed)), [], time.perf_counter()
    for trainer, n in zip(trainers, np.diff(bounds)):
        state, part = iterate(trainer, state, int(n))
        steps = history[-1]["env_steps"] if history else 0.0
        history += [{**h, "env_steps": h["env_steps"] + steps} for h in part]
    history[-1]["elapsed"] = time.perf_counter() - t0
    save(path, state, config=config_to_dict(config), identity=describe(trainers[-1].task, policy), seed=seed,
         iteration=int(state.iteration), history=history, curve=[])
    return TrainResult(state, history, [], trainers[-1])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="double_cartpole", choices=("acrobot", "cartpole", "double_cartpole"))
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    p.add_argument("--lever", default="clip", choices=LEVERS)
    p.add_argument("--vel-weight", type=float, default=0.1)
    p.add_argument("--vel-stages", type=float, nargs="+", default=[0.1, 0.03, 0.01])
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--cpu-devices", type=int, default=2)
    p.add_argument("--out", default=os.path.join(REPO, "research", "results", "swingup_levers.json"))
    args = p.parse_args(argv)
    use_cpu_cores(args.cpu_devices)
    config = CEAPGConfig.laptop(args.task)
    if args.lever in ("clip", "clipvel"):
        config = dataclasses.replace(config, max_grad_norm=1.0)
    task = laptop_task(args.task, args.bodies)
    objective = velocity_objective(task, args.vel_weight) if args.lever in ("vel", "clipvel") else None
    if args.lever == "tip":
        if args.task != "double_cartpole":
            raise SystemExit("--lever tip is the double cartpole's reward")
        objective = tip_objective(task)
    policy = laptop_policy(args.task, task)
    label = args.lever + (f"{args.vel_weight:g}" if args.lever in ("vel", "clipvel") else "")
    if args.lever == "velsched":
        label += "-".join(f"{w:g}" for w in args.vel_stages)
    rows = []
    if os.path.exists(args.out):
        with open(args.out) as f:
            rows = json.load(f)
    for seed in args.seeds:
        folder = os.path.join(REPO, "runs", "swingup_levers", f"{args.task}_{args.bodies}_{label}")
        os.makedirs(folder, exist_ok=True)
        if args.lever == "velsched":
            result = staged(config, task, policy, seed, args.vel_stages, os.path.join(folder, f"{seed}.eqx"))
        else:
            result = train(config, task, policy, jax.random.PRNGKey(seed),
                           checkpoint=os.path.join(folder, f"{seed}.eqx"), resume=True, progress=False, seed=seed,
                           objective=objective)
        pol, norm = result.trainer.policy(result.state)
        rets, bal = jax.device_get(jax.jit(lambda k: evaluate(task, pol, norm, k, EVAL_EPISODES))(
            jax.random.PRNGKey(10_000 + seed)))
        extra = {}
        if args.lever == "tip":
            eps = jax.jit(lambda k: jax.vmap(lambda kk: episode(task, pol, norm, kk))(
                jax.random.split(k, EVAL_EPISODES)))(jax.random.PRNGKey(10_000 + seed))
            extra["tip_return"] = float(jnp.mean(jnp.sum(tip_rewards(task, eps.q, eps.qd), axis=-1)))
        row = {"task": args.task, "bodies": args.bodies, "lever": label, "seed": seed,
               "return": float(np.mean(rets)), "balanced_fraction": float(np.mean(bal)),
               "best_candidate_fitness": result.history[-1]["best_return"],
               "env_steps": result.history[-1]["env_steps"], "seconds": result.history[-1]["elapsed"],
               "nonfinite": int(sum(h["nonfinite"] for h in result.history)), **extra}
        print(json.dumps(row), flush=True)
        rows = [r for r in rows if (r["task"], r["bodies"], r["lever"], r["seed"]) != (args.task, args.bodies, label,
                                                                                       seed)] + [row]
        write_json(args.out, rows, indent=1)


if __name__ == "__main__":
    main()
