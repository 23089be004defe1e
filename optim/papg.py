"""Parallel APG (the paper's ablation): ``num_runs`` independent APG runs, keep the best.

Each run starts from its own random policy initialisation (``policy.reinit``) and takes ``apg_steps`` Adam steps per
host iteration with a fresh Adam state every iteration and the same log-linear learning-rate schedule as CE-APG (so
that ``iterations x apg_steps`` matches CE-APG's interaction count, as in the paper). Runs are ``vmap``-ed and sharded
over devices exactly like CE-APG candidates; the result is the run with the best fitness (mean of its last
``fitness_window`` batch returns).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec
from jaxtyping import Array, Float, Int, PRNGKeyArray

from lagrange.tasks import AbstractTask
from lagrange.compile import compiler_options
from optim.base import Trainer
from optim.bptt import apg_steps, flatten_policy, mean_return_loss
from optim.devices import jit_replicated, population_mesh
from optim.inner_apg import InnerAPGConfig
from optim.validate import check_int
from policies import Normalizer

__all__ = ["PAPGConfig", "PAPGState", "make_trainer"]


@dataclasses.dataclass(frozen=True)
class PAPGConfig(InnerAPGConfig):
    """PAPG settings: the fields of the APG inner loop are :class:`optim.inner_apg.InnerAPGConfig`'s (the paper's
    values the defaults), ``iterations`` of ``apg_steps`` Adam steps for each run.

    Attributes:
        num_runs (int): independent runs, >= 1 and a multiple of the device count (paper: 24).
    """

    num_runs: int = 24

    def __post_init__(self):
        super().__post_init__()
        check_int(type(self).__name__, "num_runs", self.num_runs, 1)

    def env_steps_per_iteration(self, horizon: int) -> int:
        """Simulated control steps of one iteration on a task of ``horizon`` steps.

        Args:
            horizon: the task's episode length in control steps.
        """
        return self.num_runs * self.apg_steps * self.episodes * horizon

    def make_trainer(self, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
        """:func:`optim.papg.make_trainer` of this config (the arguments are documented there)."""
        return make_trainer(self, task, policy, objective=objective)


class PAPGState(NamedTuple):
    """PAPG's training state (``P`` flat policy parameters).

    Attributes:
        params (Float[Array, "num_runs P"]): every run's parameters.
        normalizers (Normalizer | None): every run's normaliser (leaves with a leading ``num_runs`` axis).
        fitness (Float[Array, "num_runs"]): every run's last fitness (-inf before the first iteration, and for a
            run that went non-finite).
        key (PRNGKeyArray): the run's key; iteration ``i`` draws from ``fold_in(key, i)``.
        iteration (Int[Array, ""]): iterations done, int32.
    """

    params: Float[Array, "runs P"]
    normalizers: Normalizer | None
    fitness: Float[Array, " runs"]
    key: Array
    iteration: Int[Array, ""]


def make_trainer(config: PAPGConfig, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
    """PAPG on ``task``; each run starts from ``policy.reinit(k)`` for its own key ``k``. The arguments are those of
    :func:`optim.apg.make_trainer` (``config`` a :class:`PAPGConfig`).

    Returns:
        The :class:`optim.Trainer`; its metrics: ``best_return``, ``mean_return`` (of the finite runs), ``nonfinite``
        (how many runs went non-finite) and ``nonfinite_members`` (which: a ``(num_runs,)`` bool mask),
        ``learning_rate``, ``env_steps``.

    Raises:
        ValueError: if ``num_runs`` is not a multiple of the device count.
    """
    objective = mean_return_loss if objective is None else objective
    _, unravel = flatten_policy(policy)
    N = config.num_runs
    mesh = population_mesh(N)
    ndev = len(mesh.devices)
    if N % ndev:
        raise ValueError(f"PAPGConfig.num_runs ({N}) must be a multiple of the device count ({ndev})")
    shard = NamedSharding(mesh, PartitionSpec("population"))
    replicated = NamedSharding(mesh, PartitionSpec())

    def init(key: PRNGKeyArray) -> PAPGState:
        keys = jax.random.split(jax.random.fold_in(key, 0x5EED), N)
        params = jax.vmap(lambda k: flatten_policy(policy.reinit(k))[0])(keys)
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
                            learning_rate=lr, truncation=config.truncation, objective=objective,
                            max_grad_norm=config.max_grad_norm)
            fit = jnp.mean(res.returns[-config.fitness_window:])
            bad = ~res.finite | ~jnp.isfinite(fit)
            return res.params, res.normalizer, jnp.where(bad, -jnp.inf, fit), bad

        p, norms, fit, bad = jax.vmap(run)(params, state.normalizers, keys)
        finite = jnp.isfinite(fit)
        metrics = {
            "best_return": jnp.max(fit),
            "mean_return": jnp.sum(jnp.where(finite, fit, 0.0)) / jnp.maximum(jnp.sum(finite), 1),
            "nonfinite": jnp.sum(bad),
            "nonfinite_members": bad,
            "learning_rate": lr,
            "env_steps": jnp.asarray(config.env_steps_per_iteration(task.horizon), jnp.float32),
        }
        return PAPGState(p, norms, fit, state.key, state.iteration + 1), metrics

    def policy_of(state: PAPGState, which: str = "best"):
        """``(policy, normalizer)`` of the run with the best fitness (``which`` is accepted for the common interface;
        PAPG has no mean)."""
        if which != "best":
            raise ValueError(f"PAPG has only its best run: which must be 'best', got {which!r}")
        i = jnp.argmax(state.fitness)
        norm = jax.tree_util.tree_map(lambda x: x[i], state.normalizers)
        return unravel(state.params[i]), norm

    return Trainer(init, jit_replicated(update, replicated, compiler_options(task.chain)), policy_of, task, config)
