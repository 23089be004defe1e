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

from optim.apg import (Trainer, _check_int, _check_pos, apg_steps, build_policy, build_task, check_common,
                       flatten_policy, log_linear_lr)
from optim.devices import candidate_mesh
from policies import Normalizer


@dataclasses.dataclass(frozen=True)
class PAPGConfig:
    """Fields as in :class:`optim.ce_apg.CEAPGConfig`; ``num_runs`` independent runs [24]."""

    task: str = "acrobot"
    num_runs: int = 24
    iterations: int = 200
    apg_steps: int = 100
    episodes: int = 4
    horizon: int = 500
    lr_start: float = 1e-3
    lr_end: float = 1e-6
    fitness_window: int = 5
    policy: str = "gru"
    width: int = 16
    normalize: bool = True
    truncation: int | None = None
    trig_observation: bool = False

    def __post_init__(self):
        check_common(self)
        c = type(self).__name__
        _check_int(c, "num_runs", self.num_runs, 1)
        _check_int(c, "iterations", self.iterations, 1)
        _check_int(c, "apg_steps", self.apg_steps, 1)
        _check_pos(c, "lr_start", self.lr_start)
        _check_pos(c, "lr_end", self.lr_end)
        _check_int(c, "fitness_window", self.fitness_window, 1)
        if self.fitness_window > self.apg_steps:
            raise ValueError(f"{c}.fitness_window must be <= apg_steps ({self.apg_steps}), got {self.fitness_window}")

    def env_steps_per_iteration(self) -> int:
        return self.num_runs * self.apg_steps * self.episodes * self.horizon

    def learning_rate(self, iteration):
        """Log-linear from ``lr_start`` at iteration 0 to ``lr_end`` at ``iterations`` (constant within one)."""
        return log_linear_lr(iteration, self.iterations, self.lr_start, self.lr_end)


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

    jitted = jax.jit(update, out_shardings=replicated)

    def update_replicated(state):
        # The state lives replicated on every device; placing it there first keeps one jit cache entry.
        return jitted(jax.device_put(state, replicated))

    return Trainer(init, update_replicated, policy, task, config)


def make_train(config: PAPGConfig, task=None):
    trainer = make_trainer(config, task)

    def train(key):
        return jax.lax.scan(lambda s, _: trainer.update(s), trainer.init(key), None, config.iterations)

    return train
