"""The acrobot's swing-up by CE-APG with a policy that also sees its observation on an upright scale.

    python -m research.acrobot_two_scale --seed 0                  # about 5-10 minutes on two cores
    python -m research.acrobot_two_scale --seed 0 --cpu-devices 1

The laptop protocol (``CEAPGConfig.laptop("acrobot")``, rods unless ``--bodies``), with one change: the policy's
input is the library's running-normalised observation *and* the same observation normalised by the frozen upright
scale of ``acrobot_balance_patches --norm upright`` (mean at upright, 0.05 for the sines and cosines, 0.5 rad/s for
the velocities, clipped to +-5), concatenated: 12 inputs instead of 6, and so (the authors' layout: GRU hidden size =
input size) a GRU hidden state of 12. The running statistics are fitted over the whole swing-up, so near upright they
resolve a lean of 0.02 rad as a few hundredths of a unit (printed for the run's final normaliser); the upright scale
as 0.4. The policy is passed to ``CEAPGConfig.make_trainer`` as a 12-input ``GRUPolicy``; the two-scale normaliser
is put in place of the running one in the state ``trainer.init`` returns (``optim.train`` has no hook for another
normaliser, so this script runs the trainer's iterations itself).

Printed: the final best policy's evaluation as in ``benchmarks.paper_tables`` (16 episodes from the fixed random
hanging starts of key ``10_000 + seed``: mean return and episodes balanced), the same from 16 upright starts, and the
training time.
"""

import argparse
import dataclasses
import json
import time

import equinox as eqx
import jax
import jax.numpy as jnp

from optim import CEAPGConfig, evaluate
from optim.devices import cpu_core_count, use_cpu_cores
from policies import GRUPolicy, Normalizer
from research._apg import WIDTH, iterate, laptop_task
from research.acrobot_balance_patches import FrozenNormalizer, upright_normalizer


class TwoScaleNormalizer(eqx.Module):
    """``concat(wide(obs), tight(obs))``: the running normaliser and a frozen one; ``update`` updates the first."""

    wide: Normalizer
    tight: FrozenNormalizer

    def update(self, obs) -> "TwoScaleNormalizer":
        return TwoScaleNormalizer(self.wide.update(obs), self.tight)

    def __call__(self, obs):
        return jnp.concatenate([self.wide(obs), self.tight(obs)], -1)


def two_scale_policy(task, width: int) -> GRUPolicy:
    """The GRU with twice the task's observation as input (and so a hidden state of that size)."""
    return GRUPolicy(2 * task.observation_size, task.action_size, width, key=jax.random.PRNGKey(0))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--iterations", type=int, default=None, help="default: the laptop preset's")
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count())
    args = p.parse_args(argv)
    use_cpu_cores(args.cpu_devices)
    cfg = CEAPGConfig.laptop("acrobot")
    if args.iterations:
        cfg = dataclasses.replace(cfg, iterations=args.iterations)
    if not cfg.normalize or cfg.authors_normalizer:
        raise SystemExit("the laptop preset is expected to normalise with a running Normalizer")
    task = laptop_task("acrobot", args.bodies)
    trainer = cfg.make_trainer(task, two_scale_policy(task, WIDTH["acrobot"]))
    state = trainer.init(jax.random.PRNGKey(args.seed))
    norm = TwoScaleNormalizer(state.normalizer, upright_normalizer(task.trig))
    state = state._replace(normalizer=norm, best_normalizer=norm)
    t0 = time.perf_counter()
    state, history = iterate(trainer, state, cfg.iterations)
    seconds = time.perf_counter() - t0
    policy, norm = trainer.policy(state)
    out = {"seed": args.seed, "bodies": args.bodies, "iterations": cfg.iterations,
           "cpu_devices": args.cpu_devices, "seconds": round(seconds),
           "best_candidate_return": float(history[-1]["best_return"]),
           # the first two observations are the links' angles or (trig) their sines: both ~ the lean near upright
           "running_units_per_0.02_rad": [round(float(u), 4) for u in 0.02 / jnp.sqrt(norm.wide.var[:2])]}
    for name, task in (("hanging", trainer.task), ("upright", dataclasses.replace(trainer.task, upright=1.0))):
        rets, bal = jax.jit(lambda k, t=task: evaluate(t, policy, norm, k, 16))(jax.random.PRNGKey(10_000 + args.seed))
        out[name] = {"return": round(float(jnp.mean(rets)), 1), "balanced_of_16": int(jnp.sum(bal))}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
