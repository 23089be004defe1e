"""Analytic policy gradients (APG): one policy, Adam on gradients back-propagated through whole episodes.

Each iteration is ``steps_per_iteration`` steps of :func:`optim.apg_steps` with the Adam state carried across
iterations and a constant learning rate.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import optax
from jaxtyping import Array, Float, Int, PRNGKeyArray

from lagrange.tasks import AbstractTask
from optim.base import AlgorithmConfig, Trainer
from optim.bptt import apg_steps, flatten_policy, mean_return_loss
from optim.validate import check_bool, check_int, check_positive
from policies import Normalizer

__all__ = ["APGConfig", "APGState", "make_trainer"]


@dataclasses.dataclass(frozen=True)
class APGConfig(AlgorithmConfig):
    """Plain APG settings.

    Fields: ``iterations`` host-loop iterations of ``steps_per_iteration`` Adam steps each; ``episodes``
    random-start episodes per step; ``learning_rate`` constant Adam step size; ``normalize`` running observation
    normalisation; ``truncation`` optional truncated-BPTT window.
    """

    iterations: int = 20
    steps_per_iteration: int = 50
    episodes: int = 4
    learning_rate: float = 1e-3
    normalize: bool = True
    truncation: int | None = None
    max_grad_norm: float | None = None

    def __post_init__(self):
        c = type(self).__name__
        check_int(c, "iterations", self.iterations, 1)
        check_int(c, "steps_per_iteration", self.steps_per_iteration, 1)
        check_int(c, "episodes", self.episodes, 1)
        check_positive(c, "learning_rate", self.learning_rate)
        check_bool(c, "normalize", self.normalize)
        if self.truncation is not None:
            check_int(c, "truncation", self.truncation, 1)
        if self.max_grad_norm is not None:
            check_positive(c, "max_grad_norm", self.max_grad_norm)

    def make_trainer(self, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
        return make_trainer(self, task, policy, objective=objective)


class APGState(NamedTuple):
    """APG's training state: parameters ``(P,)``, Adam's state, the normaliser, the run's key, iterations done."""

    params: Float[Array, " P"]
    opt_state: Any
    normalizer: Normalizer | None
    key: Array
    iteration: Int[Array, ""]


def make_trainer(config: APGConfig, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
    """APG on ``task`` from ``policy.reinit(fold_in(key, 0x5EED))``."""
    objective = mean_return_loss if objective is None else objective
    _, unravel = flatten_policy(policy)
    adam = optax.scale_by_adam()
    steps = config.steps_per_iteration

    def init(key: PRNGKeyArray) -> APGState:
        params, _ = flatten_policy(policy.reinit(jax.random.fold_in(key, 0x5EED)))
        norm = Normalizer.create(task.observation_size, dtype=params.dtype) if config.normalize else None
        return APGState(params, adam.init(params), norm, jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def update(state: APGState):
        key = jax.random.fold_in(state.key, state.iteration)
        res = apg_steps(task, unravel, state.params, state.normalizer, key, steps=steps, episodes=config.episodes,
                        learning_rate=config.learning_rate, truncation=config.truncation, objective=objective,
                        opt_state=state.opt_state, max_grad_norm=config.max_grad_norm)
        rets = res.returns
        metrics = {
            "best_return": jnp.max(jnp.where(jnp.isfinite(rets), rets, -jnp.inf)),
            "mean_return": jnp.mean(rets[-min(5, steps):]),
            "nonfinite": (~res.finite).astype(jnp.int32),
            "env_steps": jnp.asarray(steps * config.episodes * task.horizon, jnp.float32),
        }
        return APGState(res.params, res.opt_state, res.normalizer, state.key, state.iteration + 1), metrics

    def policy_of(state: APGState, which: str = "best"):
        """``(policy, normalizer)``: APG's one policy."""
        if which != "best":
            raise ValueError(f"APG has one policy: which must be 'best', got {which!r}")
        return unravel(state.params), state.normalizer

    return Trainer(init, jax.jit(update), policy_of, task, config)
