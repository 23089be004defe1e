"""Changes to CE-APG on the balance-only acrobot (three objectives, two normalisers), none of which teaches it to hold.

    python -m research.acrobot_balance_patches --patch none --seed 0        # about 2 minutes each
    python -m research.acrobot_balance_patches --patch terminal --seed 0
    python -m research.acrobot_balance_patches --patch select1000 --seed 0
    python -m research.acrobot_balance_patches --patch none --curriculum --seed 0   # 100 -> ... -> 500
    python -m research.acrobot_balance_patches --patch unwrapped --curriculum --seed 0
    python -m research.acrobot_balance_patches --norm upright [--curriculum] --seed 0

The setting is ``research.balance_horizon``'s (rods unless ``--bodies``; every training episode starts upright;
the laptop protocol for 60 iterations): 100-step training episodes, or with ``--curriculum`` its curriculum 100 -> 150
-> 200 -> 300 -> 400 -> 500 (10 iterations each). The patch changes CE-APG's APG loss or its fitness:

- ``none``: unchanged (the library's loss and fitness);
- ``terminal``: the APG loss adds ``10 log(sum th^2 + 0.1 sum dth^2)`` at each training episode's last state (wrapped
  angles, 0 = upright; the batch mean); the fitness stays the return (the ``objective`` of
  ``CEAPGConfig.make_trainer``, with the term in the gradient only: ``research._apg.gradient_only``);
- ``select1000``: the fitness is the mean return of two forward 1000-step episodes from upright with the candidate's
  post-APG parameters instead of its last batch returns (the gradient unchanged). The library's trainer scores a
  candidate by its APG batch returns only, so this patch runs ``research._apg.ce_apg_with_fitness``: the same CE-APG
  iteration on one device (as this script has always run), the fitness replaced;
- ``unwrapped``: the training reward (gradient and fitness) is the paper's with *unwrapped* angles,
  ``10 - sum (q - offset)^2 - 0.01 sum dq^2``, so a full turn costs ``(2 pi)^2`` per step instead of nothing (the
  ``objective`` of ``CEAPGConfig.make_trainer``).

``--norm`` sets the observation normaliser: ``running`` (the library's: running mean and variance of every
observation seen, so early falls widen it for good) or ``upright`` (frozen at the upright observation with standard
deviations of 0.05 for the angles, or their sines and cosines, and 0.5 rad/s for the velocities: 0.02 rad, the edge
of the saturated LQR's basin, is 0.4 normalised units; beyond about 0.25 rad the inputs clip at +-5). It is put in
place of the running normaliser in the state ``trainer.init`` returns (``optim.train`` has no hook for another
normaliser, so this script runs the trainer's iterations itself).

Evaluation is the paper's task from 16 upright starts (key ``10_000 + seed``, as ``balance_horizon``) over 500 steps:
printed are the best policy's mean return and the episodes balanced.
"""

import argparse
import dataclasses
import json
import time

import jax
import jax.numpy as jnp

from lagrange.tasks import wrap
from optim import episode
from policies import Normalizer
from research._apg import ce_apg_with_fitness, gradient_only, iterate
from research.balance_horizon import evaluate, setup

PATCHES = ("none", "terminal", "select1000", "unwrapped")
NORMS = ("running", "upright")
CURRICULUM = (100, 150, 200, 300, 400)


class FrozenNormalizer(Normalizer):
    """A normaliser whose statistics never change: ``update`` returns it unchanged."""

    def update(self, obs) -> "FrozenNormalizer":
        return self


def upright_normalizer(trig: bool, angle_std: float = 0.05, velocity_std: float = 0.5) -> FrozenNormalizer:
    """Frozen at the upright observation: ``(th, dth)``, or ``(sin th, cos th, dth)`` with ``trig`` (the laptop
    preset's), the angle terms (sines and cosines alike) scaled by ``angle_std``, the velocities by ``velocity_std``."""
    if trig:
        mean = jnp.array([0.0, 0.0, 1.0, 1.0, 0.0, 0.0])
        std = jnp.array([angle_std] * 4 + [velocity_std] * 2)
    else:
        mean = jnp.zeros(4)
        std = jnp.array([angle_std] * 2 + [velocity_std] * 2)
    return FrozenNormalizer(mean, std**2, jnp.asarray(1.0))


def _offset(n):
    return jnp.zeros(n).at[0].set(jnp.pi)  # first pole: 0 = hanging in q, upright at pi


def terminal_objective(first_pole: int):
    """The APG objective with the terminal term in the gradient (the reported return stays the batch return)."""

    def term(eps):
        q, qd = eps.q[:, -1, first_pole:], eps.qd[:, -1, first_pole:]  # each episode's last state
        th = wrap(q - _offset(q.shape[-1]))  # as AbstractTask.angles
        return jnp.mean(10 * jnp.log(jnp.sum(th**2, -1) + 0.1 * jnp.sum(qd**2, -1)))

    return gradient_only(term)


def unwrapped_objective(first_pole: int):
    """Minus the mean return of the paper's reward with unwrapped angles."""

    def objective(eps):
        q, qd = eps.q[:, 1:, first_pole:], eps.qd[:, 1:, first_pole:]  # the rewards' next states
        r = 10.0 - jnp.sum((q - _offset(q.shape[-1])) ** 2, -1) - 0.01 * jnp.sum(qd**2, -1)
        return -jnp.mean(jnp.sum(r, -1))

    return objective


def forward_fitness(horizon: int = 1000, episodes: int = 2):
    """``fitness(stage_task, unravel, result, key)``: the mean return of ``episodes`` forward ``horizon``-step
    episodes of the candidate's post-APG parameters and normaliser (keys from ``fold_in(key, 1_000_003)``)."""

    def fitness(task, unravel, res, key):
        long = dataclasses.replace(task, horizon=horizon)
        keys = jax.random.split(jax.random.fold_in(key, 1_000_003), episodes)
        return jnp.mean(jax.vmap(lambda k: episode(long, unravel(res.params), res.normalizer, k).ret)(keys))

    return fitness


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--patch", choices=PATCHES, default="none")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--curriculum", action="store_true", help="100 -> 150 -> 200 -> 300 -> 400 -> 500 steps")
    p.add_argument("--iterations", type=int, default=60)
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    p.add_argument("--norm", default="running", choices=NORMS, help="observation normaliser (module docstring)")
    args = p.parse_args(argv)
    cfg, task, policy = (setup("acrobot", 500, args.iterations, CURRICULUM, args.bodies) if args.curriculum
                         else setup("acrobot", 100, args.iterations, (), args.bodies))
    if args.patch == "select1000":
        trainer = ce_apg_with_fitness(cfg, task, policy, fitness=forward_fitness())
    else:
        objective = {"terminal": terminal_objective(task.first_pole),
                     "unwrapped": unwrapped_objective(task.first_pole)}.get(args.patch)
        trainer = cfg.make_trainer(task, policy, objective=objective)
    state = trainer.init(jax.random.PRNGKey(args.seed))
    if args.norm == "upright":  # the trainer's initial state with the frozen normaliser in place of the running one
        frozen = upright_normalizer(task.trig)
        state = state._replace(normalizer=frozen, best_normalizer=frozen)
    t0 = time.perf_counter()
    state, history = iterate(trainer, state, cfg.iterations)
    policy, norm = trainer.policy(state)
    up = dataclasses.replace(trainer.task, upright=1.0, horizon=500)
    out = {"patch": args.patch, "norm": args.norm, "curriculum": args.curriculum, "seed": args.seed,
           "bodies": args.bodies,
           "iterations": cfg.iterations, "seconds": round(time.perf_counter() - t0),
           "best_candidate_return": float(history[-1]["best_return"]),
           **evaluate(up, policy, norm, jax.random.PRNGKey(10_000 + args.seed))}
    out["balanced_of_16"] = round(out["balanced_fraction"] * 16)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
