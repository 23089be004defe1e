"""SHAC's typed configuration: the authors' cartpole-swing-up settings by default."""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax.numpy as jnp
import numpy as np

from optim.base import AlgorithmConfig
from optim.shac.trainer import make_trainer
from optim.validate import check_bool, check_int, check_real

__all__ = ["SHACConfig"]


@dataclasses.dataclass(frozen=True)
class SHACConfig(AlgorithmConfig):
    """SHAC settings; the defaults are the authors' cartpole swing-up config
    (``examples/cfg/shac/cartpole_swing_up.yaml`` in NVlabs/DiffRL; their names in brackets). The task (its
    ``horizon`` is the authors' ``episode_length``) and the actor (:class:`policies.Actor`, their ``actor_mlp`` units
    and ``actor_logstd_init``) are passed to :func:`optim.train`, not set here.

    num_envs: parallel environments [num_actors = 64].
    short_horizon: steps per window, h [steps_num = 32].
    iterations: training epochs, one window each [max_epochs = 500].
    gamma: discount [0.99].
    lam: TD(lambda) parameter of the critic targets [lambda = 0.95].
    critic_iterations: passes over the window's data per epoch [16].
    critic_minibatches: contiguous minibatches per pass [num_batch = 4].
    target_alpha: target critic soft update ``target = alpha target + (1 - alpha) critic`` [target_critic_alpha = 0.2].
    actor_lr, critic_lr: initial Adam step sizes [1e-2, 1e-3], decayed linearly to lr_end [1e-5] (lr_schedule = linear).
    adam_b1, adam_b2, adam_eps: Adam's betas and epsilon [betas = (0.7, 0.95); PyTorch eps 1e-8].
    actor_grad_norm, critic_grad_norm: global gradient-norm clip, None = none [grad_norm = 1.0, truncate_grads].
    critic_units: hidden widths of the critic's ELU + LayerNorm MLP [critic_mlp (64, 64)].
    normalize: running observation mean/std normalisation [obs_rms = True].
    """

    num_envs: int = 64
    short_horizon: int = 32
    iterations: int = 500
    gamma: float = 0.99
    lam: float = 0.95
    critic_iterations: int = 16
    critic_minibatches: int = 4
    target_alpha: float = 0.2
    actor_lr: float = 1e-2
    critic_lr: float = 1e-3
    lr_end: float = 1e-5
    adam_b1: float = 0.7
    adam_b2: float = 0.95
    adam_eps: float = 1e-8
    actor_grad_norm: float | None = 1.0
    critic_grad_norm: float | None = 1.0
    critic_units: tuple[int, ...] = (64, 64)
    normalize: bool = True

    def __post_init__(self):
        c = "SHACConfig"
        check_int(c, "num_envs", self.num_envs, 1)
        check_int(c, "short_horizon", self.short_horizon, 1)
        check_int(c, "iterations", self.iterations, 1)
        check_int(c, "critic_iterations", self.critic_iterations, 0)
        check_int(c, "critic_minibatches", self.critic_minibatches, 1)
        if self.critic_minibatches > self.num_envs * self.short_horizon:
            raise ValueError(f"SHACConfig.critic_minibatches must be <= num_envs * short_horizon "
                             f"({self.num_envs * self.short_horizon}), got {self.critic_minibatches}")
        check_real(c, "gamma", self.gamma, 0, 1, lo_open=True)
        check_real(c, "lam", self.lam, 0, 1)
        check_real(c, "target_alpha", self.target_alpha, 0, 1)
        for name in ("actor_lr", "critic_lr", "lr_end", "adam_eps"):
            check_real(c, name, getattr(self, name), 0, lo_open=True)
        check_real(c, "adam_b1", self.adam_b1, 0, 1, hi_open=True)
        check_real(c, "adam_b2", self.adam_b2, 0, 1, hi_open=True)
        for name in ("actor_grad_norm", "critic_grad_norm"):
            if getattr(self, name) is not None:
                check_real(c, name, getattr(self, name), 0, lo_open=True)
        units = self.critic_units
        if not isinstance(units, tuple) or not units or any(
                isinstance(u, bool) or not isinstance(u, (int, np.integer)) or u < 1 for u in units):
            raise ValueError(f"SHACConfig.critic_units must be a non-empty tuple of integers >= 1, got {units!r}")
        check_bool(c, "normalize", self.normalize)

    def env_steps_per_epoch(self) -> int:
        return self.num_envs * self.short_horizon

    def learning_rates(self, epoch):
        """``(actor_lr, critic_lr)`` of epoch ``epoch`` (0-based): linear from the start value to ``lr_end``."""
        frac = jnp.asarray(epoch) / self.iterations
        return (self.actor_lr + (self.lr_end - self.actor_lr) * frac,
                self.critic_lr + (self.lr_end - self.critic_lr) * frac)

    def make_trainer(self, task, policy, *, objective: Callable | None = None):
        """SHAC on ``task`` with the actor ``policy`` (a :class:`policies.Actor`); ``objective`` is not used (SHAC's
        actor loss is its own) and must be None."""
        if objective is not None:
            raise ValueError("SHAC has its own actor loss: objective must be None")
        return make_trainer(self, task, policy)
