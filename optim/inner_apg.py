"""The APG inner loop every member of a population runs, shared by CE-APG's candidates and PAPG's runs: its settings
(:class:`InnerAPGConfig`) and the CE-APG authors' log-linear learning-rate schedule (:func:`log_linear_lr`)."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from optim.base import AlgorithmConfig
from optim.validate import check_bool, check_int, check_positive

__all__ = ["InnerAPGConfig", "log_linear_lr"]


def log_linear_lr(iteration: Int[ArrayLike, ""], iterations: int, lr_start: float,
                  lr_end: float) -> Float[Array, ""]:
    """The CE-APG authors' learning-rate schedule, ``lr_start^((T - i) / T) * lr_end^(i / T)``.

    Args:
        iteration: ``i``, the 0-based iteration (an int or a traced integer scalar); from ``i = T`` on (a run
            continued past its planned iterations) the rate stays at ``lr_end``.
        iterations: ``T``, the iterations the schedule spans, >= 1.
        lr_start: the rate at iteration 0, > 0.
        lr_end: the rate at iteration ``T``, > 0.

    Returns:
        The learning rate, a float32 scalar.
    """
    # clamped as an integer, so the float arithmetic below is the same program as before the clamp existed: the
    # chaotic swing-up training turns a one-ulp change of the learning rate into a different run
    frac = jnp.asarray(jnp.minimum(iteration, iterations), jnp.float32) / iterations
    return jnp.exp((1 - frac) * np.log(lr_start) + frac * np.log(lr_end))


@dataclasses.dataclass(frozen=True)
class InnerAPGConfig(AlgorithmConfig):
    """The settings of the APG inner loop, shared by :class:`optim.CEAPGConfig` and :class:`optim.PAPGConfig`: each
    of ``iterations`` host iterations runs ``apg_steps`` Adam steps (a fresh Adam state every iteration,
    :func:`optim.apg_steps`) on ``episodes`` random-start episodes per step, at a learning rate log-linear from
    ``lr_start`` to ``lr_end`` over the iterations (:func:`log_linear_lr`). The paper's values are the defaults.

    Attributes:
        iterations (int): host iterations, >= 1 (paper: 200).
        apg_steps (int): Adam steps per member per iteration, >= 1 (CE-APG allows 0: the plain cross-entropy method)
            (paper: 100).
        episodes (int): random-start episodes per APG step, >= 1 (paper: 4).
        lr_start (float): Adam's step size at iteration 0, > 0 (paper: 1e-3).
        lr_end (float): Adam's step size at iteration ``iterations``, > 0, constant within an iteration
            (paper: 1e-6).
        fitness_window (int): a member's fitness is the mean of its last ``fitness_window`` batch returns,
            1 <= fitness_window <= apg_steps (paper: 5).
        normalize (bool): running observation normalisation, clipped to +-5 standard deviations (paper: True).
        truncation (int | None): truncated-BPTT window in control steps, >= 1; None back-propagates through the
            whole episode (paper: None).
        max_grad_norm (float | None): rescale each APG step's gradient to at most this global 2-norm before Adam
            sees it, > 0; None clips nothing (paper: None, the authors' ``adaptive_grad_clip(1e9)`` never engages).
    """

    iterations: int = 200
    apg_steps: int = 100
    episodes: int = 4
    lr_start: float = 1e-3
    lr_end: float = 1e-6
    fitness_window: int = 5
    normalize: bool = True
    truncation: int | None = None
    max_grad_norm: float | None = None

    min_apg_steps: ClassVar[int] = 1  # CE-APG allows 0: the plain cross-entropy method

    def __post_init__(self):
        c = type(self).__name__
        check_int(c, "iterations", self.iterations, 1)
        check_int(c, "apg_steps", self.apg_steps, self.min_apg_steps)
        check_int(c, "episodes", self.episodes, 1)
        check_positive(c, "lr_start", self.lr_start)
        check_positive(c, "lr_end", self.lr_end)
        check_int(c, "fitness_window", self.fitness_window, 1)
        check_bool(c, "normalize", self.normalize)
        if self.truncation is not None:
            check_int(c, "truncation", self.truncation, 1)
        if self.max_grad_norm is not None:
            check_positive(c, "max_grad_norm", self.max_grad_norm)
        if self.apg_steps and self.fitness_window > self.apg_steps:
            raise ValueError(f"{c}.fitness_window must be <= apg_steps ({self.apg_steps}), got {self.fitness_window}")

    def learning_rate(self, iteration: Int[ArrayLike, ""]) -> Float[Array, ""]:
        """The learning rate: :func:`log_linear_lr` from ``lr_start`` at iteration 0 to ``lr_end`` at ``iterations``
        (constant within one).

        Args:
            iteration: the 0-based iteration, an int or a traced integer.
        """
        return log_linear_lr(iteration, self.iterations, self.lr_start, self.lr_end)
