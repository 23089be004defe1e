"""Analytic policy gradients (APG): one policy, Adam on gradients back-propagated through whole episodes.

Each iteration is ``steps_per_iteration`` steps of :func:`optim.apg_steps` with the Adam state carried across
iterations and a constant learning rate.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple
from collections.abc import Callable

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
    """Plain APG settings: one policy, Adam on gradients back-propagated through whole episodes.

    Attributes:
        iterations (int): host-loop iterations, >= 1.
        steps_per_iteration (int): Adam steps per iteration, >= 1 (the Adam state carries across iterations).
        episodes (int): random-start episodes per step, >= 1.
        learning_rate (float): Adam's constant step size, > 0.
        normalize (bool): running observation normalisation (clipped to +-5 standard deviations).
        truncation (int | None): truncated-BPTT window in control steps, >= 1; None: the whole episode.
        max_grad_norm (float | None): rescale each gradient to at most this global 2-norm before Adam, > 0; None
            clips nothing.
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
        """:func:`optim.apg.make_trainer` of this config (the arguments are documented there)."""
        return make_trainer(self, task, policy, objective=objective)


class APGState(NamedTuple):
    """APG's training state (``P`` flat policy parameters).

    Attributes:
        params (Float[Array, "P"]): the policy's parameters.
        opt_state: Adam's state (``optax.scale_by_adam``'s).
        normalizer (Normalizer | None): the observation normaliser (None without normalisation).
        key (PRNGKeyArray): the run's key; iteration ``i`` draws from ``fold_in(key, i)``.
        iteration (Int[Array, ""]): iterations done, int32.
    """

    params: Float[Array, " P"]
    opt_state: Any
    normalizer: Normalizer | None
    key: Array
    iteration: Int[Array, ""]


def make_trainer(config: APGConfig, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
    """APG on ``task``, starting from ``policy.reinit(fold_in(key, 0x5EED))``.

    Args:
        config: the settings.
        task: the task to train on, and the one the trainer evaluates.
        policy: the policy module, its architecture (the algorithm draws the initial weights from the run's key).
        objective: the loss of a batch of episodes each APG step minimises (default :func:`optim.mean_return_loss`,
            minus the mean return).

    Returns:
        The :class:`optim.Trainer`; its metrics: ``best_return`` and ``mean_return`` (of the last 5 batches),
        ``nonfinite`` (1 when an update was skipped), ``env_steps``.
    """
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
