"""Do exploding BPTT gradients freeze the candidates' Adam? Gradient-norm statistics along a CE-APG run.

    python -m research.apg_gradient_norms --task double_cartpole --at 0 25 75 149
    python -m research.apg_gradient_norms --task double_cartpole --bodies brax_v1 --protocol paper --at 0 20 60

Trains CE-APG (``CEAPGConfig.laptop(task)`` or ``.paper()``, ``--set FIELD=VALUE`` to change a field, e.g.
``--set max_grad_norm=1.0``) with ``trainer.update`` and, before each iteration named by ``--at``, replays that
iteration's candidates (the same draws of parameters, keys, learning rate and normaliser as the update) through
:func:`optim.apg_steps`, whose ``grad_norms`` give each APG step's gradient norm. Per iteration it records, over the
candidates: the median norm, the ratio of each candidate's largest norm to its median (a spike), and Adam's step
shrink after such spikes in the scalar approximation ``|step_k| ~ g_k / sqrt(mean_{j<=k} g_j^2)`` (beta2 = 0.999
remembers every spike of a 25-100 step run; bias correction makes the memory the plain mean): the median over the
candidates' second half of steps of ``sqrt(mean_{j<=k} g_j^2) / g_k``, 1 for a run of equal norms, ``sqrt(k)`` after
a single huge spike. Writes ``research/results/apg_gradient_norms_<task>[_<bodies>]_<protocol>[_<tag>].json``.
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

from benchmarks._cli import add_bodies_flag, bodies_suffix
from optim import CEAPGConfig, apg_steps, episode, flatten_policy
from optim.checkpoint import write_json
from optim.devices import use_cpu_cores
from research._apg import laptop_policy, laptop_task
from research._cli import REPO


def candidate_norms(config: CEAPGConfig, trainer, policy, state):
    """``(grad_norms (K, steps), returns (K, steps))`` of the candidates ``trainer.update(state)`` is about to run."""
    _, unravel = flatten_policy(policy)
    K = config.num_candidates
    key = jax.random.fold_in(state.key, state.iteration)
    k_eps, k_run = jax.random.split(key)
    lr = config.learning_rate(state.iteration)
    P = state.mean.size
    thetas = state.mean + state.std * jax.random.normal(k_eps, (K, P), state.mean.dtype)
    keys = jax.random.split(k_run, K)
    task = trainer.task
    norm = state.normalizer
    if config.authors_normalizer:  # the update's first act: one episode of the mean refreshes the shared normaliser
        norm = norm.update(episode(task, unravel(state.mean), norm, keys[0]).obs)
    if config.warmup_horizons or config.upright_starts or config.train_noise is not None:
        raise SystemExit("apg_gradient_norms: curricula are not replayed; leave warmup_horizons, upright_starts and "
                         "train_noise at their defaults")

    def one(theta, k):
        res = apg_steps(task, unravel, theta, norm, k, steps=config.apg_steps, episodes=config.episodes,
                        learning_rate=lr, truncation=config.truncation,
                        update_normalizer=not config.authors_normalizer, max_grad_norm=config.max_grad_norm)
        return res.grad_norms, res.returns

    return jax.vmap(one)(thetas, keys)


def summarise(norms: np.ndarray, returns: np.ndarray) -> dict:
    finite = np.isfinite(norms).all(axis=1)
    g = norms[finite]
    out = {"candidates": int(norms.shape[0]), "nonfinite_candidates": int((~finite).sum())}
    if not len(g):
        return out
    med = np.median(g, axis=1)
    spike = g.max(axis=1) / med
    k = np.arange(1, g.shape[1] + 1)
    rms_so_far = np.sqrt(np.cumsum(g**2, axis=1) / k)
    shrink = np.median((rms_so_far / g)[:, g.shape[1] // 2:], axis=1)
    out.update({
        "grad_norm_median": float(np.median(g)),
        "grad_norm_p90": float(np.percentile(g, 90)),
        "grad_norm_max": float(g.max()),
        "spike_ratio_median": float(np.median(spike)),
        "spike_ratio_max": float(spike.max()),
        "candidates_spike_over_100": int((spike > 100).sum()),
        "adam_shrink_median": float(np.median(shrink)),
        "adam_shrink_max": float(shrink.max()),
        "return_first_5": float(np.mean(returns[finite][:, :5])),
        "return_last_5": float(np.mean(returns[finite][:, -5:])),
    })
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="double_cartpole", choices=("acrobot", "cartpole", "double_cartpole"))
    add_bodies_flag(p)
    p.add_argument("--protocol", default="laptop", choices=("laptop", "paper"))
    p.add_argument("--at", type=int, nargs="+", default=[0, 25, 75, 149], help="iterations to replay (0-based)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="change a config field")
    p.add_argument("--tag", default="", help="suffix of the result file")
    p.add_argument("--cpu-devices", type=int, default=2)
    args = p.parse_args(argv)
    use_cpu_cores(args.cpu_devices)
    from benchmarks.paper_tables import parse_overrides  # the same FIELD=VALUE parsing as the paper tables

    config = CEAPGConfig.laptop(args.task) if args.protocol == "laptop" else CEAPGConfig.paper()
    config = dataclasses.replace(config, **parse_overrides(args.set))
    if args.protocol == "paper":
        task = laptop_task(args.task, args.bodies, **({"trig": False} if args.task == "acrobot" else {}))
    else:
        task = laptop_task(args.task, args.bodies)
    policy = laptop_policy(args.task, task)
    trainer = config.make_trainer(task, policy)
    state = trainer.init(jax.random.PRNGKey(args.seed))
    replay = jax.jit(lambda s: candidate_norms(config, trainer, policy, s))
    rows, t0 = [], time.perf_counter()
    for it in range(max(args.at) + 1):
        if it in args.at:
            norms, rets = jax.device_get(replay(state))
            rows.append({"iteration": it, "learning_rate": float(config.learning_rate(it)),
                         "std": float(jnp.mean(state.std)), **summarise(np.asarray(norms), np.asarray(rets))})
            print(json.dumps(rows[-1]), flush=True)
        state, metrics = trainer.update(state)
        if it in args.at:
            rows[-1]["best_fitness"] = float(metrics["best_return"])
    name = (f"apg_gradient_norms_{args.task}{bodies_suffix(args.bodies)}_{args.protocol}"
            f"{'_' + args.tag if args.tag else ''}")
    out = os.path.join(REPO, "research", "results", name + ".json")
    write_json(out, {"config": {k: getattr(config, k) for k in config.__dataclass_fields__}, "seed": args.seed,
                     "task": args.task, "bodies": args.bodies, "seconds": time.perf_counter() - t0, "rows": rows},
               indent=1)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
