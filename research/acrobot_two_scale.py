"""The acrobot's swing-up by CE-APG with a policy that also sees its observation on an upright scale.

    python -m research.acrobot_two_scale --seed 0                  # about 5-10 minutes on two cores
    python -m research.acrobot_two_scale --seed 0 --cpu-devices 1

The laptop protocol (``CEAPGConfig.laptop("acrobot")``, rods unless ``--bodies``), with one change: the policy's
input is the library's running-normalised observation *and* the same observation normalised by the frozen upright
scale of ``acrobot_balance_patches --norm upright`` (mean at upright, 0.05 for the sines and cosines, 0.5 rad/s for
the velocities, clipped to +-5), concatenated: 12 inputs instead of 6, and so (the authors' layout: GRU hidden size =
input size) a GRU hidden state of 12. The running statistics are fitted over the whole swing-up, so near upright they
resolve a lean of 0.02 rad as a few hundredths of a unit (printed for the run's final normaliser); the upright scale
as 0.4.

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

from optim._loop import run
from optim.apg import evaluate
import optim.ce_apg as ce_apg
from optim.devices import cpu_core_count, use_cpu_cores
from policies import GRUPolicy, Normalizer
from research.acrobot_balance_patches import FrozenNormalizer, upright_normalizer


class TwoScaleNormalizer(eqx.Module):
    """``concat(wide(obs), tight(obs))``: the running normaliser and a frozen one; ``update`` updates the first."""

    wide: Normalizer
    tight: FrozenNormalizer

    def update(self, obs) -> "TwoScaleNormalizer":
        return TwoScaleNormalizer(self.wide.update(obs), self.tight)

    def __call__(self, obs):
        return jnp.concatenate([self.wide(obs), self.tight(obs)], -1)


def two_scale_policy(cfg, task, key):
    return GRUPolicy(2 * task.observation_size, task.action_size, cfg.width, key=key)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--iterations", type=int, default=None, help="default: the laptop preset's")
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count())
    args = p.parse_args(argv)
    use_cpu_cores(args.cpu_devices)
    cfg = ce_apg.CEAPGConfig.laptop("acrobot", bodies=args.bodies)
    if args.iterations:
        cfg = dataclasses.replace(cfg, iterations=args.iterations)
    if not cfg.normalize or cfg.policy != "gru":
        raise SystemExit("the laptop preset is expected to normalise and use the GRU policy")
    ce_apg.build_policy = two_scale_policy
    trainer = ce_apg.make_trainer(cfg)
    base_init = trainer.init

    def init(key):
        state = base_init(key)
        norm = TwoScaleNormalizer(state.normalizer, upright_normalizer(cfg.trig_observation))
        return state._replace(normalizer=norm, best_normalizer=norm)

    trainer = trainer._replace(init=init)
    t0 = time.perf_counter()
    state, history = run(trainer, jax.random.PRNGKey(args.seed), iterations=cfg.iterations, progress=False,
                         seed=args.seed)
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
