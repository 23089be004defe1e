"""Parallel APG (the paper's ablation): ``num_runs`` independent APG runs, keep the best.

Each run starts from its own random policy initialisation and takes ``apg_steps`` Adam steps per
host iteration with a fresh Adam state every iteration and the same log-linear learning-rate
schedule as CE-APG (so that ``iterations x apg_steps`` matches CE-APG's interaction count, as in
the paper). Runs are ``vmap``-ed and sharded over devices exactly like CE-APG candidates; the
result is the run with the best fitness (mean of its last ``fitness_window`` batch returns).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec

from optim.apg import (InnerAPGConfig, Trainer, _check_int, apg_steps, build_policy, build_task, flatten_policy,
                       scan_train)
from optim.devices import candidate_mesh, jit_replicated
from policies import Normalizer


@dataclasses.dataclass(frozen=True)
class PAPGConfig(InnerAPGConfig):
    """Fields as in :class:`optim.ce_apg.CEAPGConfig` (the shared ones in :class:`optim.apg.InnerAPGConfig`);
    ``num_runs`` independent runs [24]."""

    num_runs: int = 24

    def __post_init__(self):
        super().__post_init__()
        _check_int(type(self).__name__, "num_runs", self.num_runs, 1)

    def env_steps_per_iteration(self) -> int:
        return self.num_runs * self.apg_steps * self.episodes * self.horizon


class PAPGState(NamedTuple):
    params: jax.Array  # (num_runs, P)
    normalizers: Normalizer | None  # leaves with a leading num_runs axis
    fitness: jax.Array  # (num_runs,)
    key: jax.Array
    iteration: jax.Array


def make_trainer(config: PAPGConfig, task=None) -> Trainer:
    task = build_task(config, task)
    _, unravel = flatten_policy(build_policy(config, task, jax.random.PRNGKey(0)))
    N = config.num_runs
    mesh = candidate_mesh(N)
    ndev = len(mesh.devices)
    if N % ndev:
        raise ValueError(f"PAPGConfig.num_runs ({N}) must be a multiple of the device count ({ndev})")
    shard = NamedSharding(mesh, PartitionSpec("candidates"))
    replicated = NamedSharding(mesh, PartitionSpec())

    def init(key) -> PAPGState:
        keys = jax.random.split(jax.random.fold_in(key, 0x5EED), N)
        params = jax.vmap(lambda k: flatten_policy(build_policy(config, task, k))[0])(keys)
        norm = Normalizer.create(task.observation_size, dtype=params.dtype) if config.normalize else None
        norms = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (N,) + x.shape), norm)
        return PAPGState(params, norms, jnp.full(N, -jnp.inf, params.dtype), jnp.asarray(key),
                         jnp.asarray(0, jnp.int32))

    def update(state: PAPGState):
        key = jax.random.fold_in(state.key, state.iteration)
        lr = config.learning_rate(state.iteration)
        keys = jax.lax.with_sharding_constraint(jax.random.split(key, N), shard)
        params = jax.lax.with_sharding_constraint(state.params, shard)

        def run(p, norm, k):
            res = apg_steps(task, unravel, p, norm, k, steps=config.apg_steps, episodes=config.episodes,
                            learning_rate=lr, truncation=config.truncation)
            fit = jnp.mean(res.returns[-config.fitness_window:])
            bad = ~res.finite | ~jnp.isfinite(fit)
            return res.params, res.normalizer, jnp.where(bad, -jnp.inf, fit), bad

        p, norms, fit, bad = jax.vmap(run)(params, state.normalizers, keys)
        finite = jnp.isfinite(fit)
        metrics = {
            "best_return": jnp.max(fit),
            "mean_return": jnp.sum(jnp.where(finite, fit, 0.0)) / jnp.maximum(jnp.sum(finite), 1),
            "nonfinite": jnp.sum(bad),
            "learning_rate": lr,
            "env_steps": jnp.asarray(config.env_steps_per_iteration(), jnp.float32),
        }
        return PAPGState(p, norms, fit, state.key, state.iteration + 1), metrics

    def policy(state: PAPGState, which: str = "best"):
        i = jnp.argmax(state.fitness)
        norm = jax.tree_util.tree_map(lambda x: x[i], state.normalizers)
        return unravel(state.params[i]), norm

    return Trainer(init, jit_replicated(update, replicated), policy, task, config)


def make_train(config: PAPGConfig, task=None):
    """``train(key) -> (final state, per-iteration metrics)``: the whole run as one jittable function."""
    return scan_train(make_trainer(config, task), config.iterations)
