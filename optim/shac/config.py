"""SHAC's typed configuration (the authors' cartpole-swing-up numbers by default) and the tasks it knows by name."""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax.numpy as jnp
import numpy as np

from lagrange.shac_cartpole import shac_cartpole
from lagrange.tasks import BODIES, TASKS
from lagrange.tasks import make_task as make_paper_task


TASKS_SHAC: dict[str, Callable] = {**TASKS, "shac_cartpole": shac_cartpole}
"""The tasks SHAC is configured for by name: the CE-APG paper's three and the SHAC authors' cartpole."""


def make_task(name: str, bodies: str = "rods"):
    """The task ``name`` (one of :data:`TASKS_SHAC`); a paper task on ``bodies`` (:func:`lagrange.tasks.make_task`)."""
    if name not in TASKS_SHAC:
        raise ValueError(f"task must be one of {sorted(TASKS_SHAC)}, got {name!r}")
    if name in TASKS:
        return make_paper_task(name, bodies)
    if bodies != "rods":
        raise ValueError(f"bodies={bodies!r} is for the paper tasks {sorted(TASKS)}; {name!r} has its own bodies")
    return TASKS_SHAC[name]()


def _int(name, v, minimum):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise ValueError(f"SHACConfig.{name} must be an integer >= {minimum}, got {v!r}")


def _real(name, v, lo=None, hi=None, *, lo_open=False, hi_open=False):
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"SHACConfig.{name} must be a real number, got {v!r}") from None
    bad = not np.isfinite(x)
    if lo is not None:
        bad |= x <= lo if lo_open else x < lo
    if hi is not None:
        bad |= x >= hi if hi_open else x > hi
    if bad:
        lb = "" if lo is None else ("(" if lo_open else "[") + f"{lo}"
        ub = "" if hi is None else f"{hi}" + (")" if hi_open else "]")
        raise ValueError(f"SHACConfig.{name} must be a finite number in {lb or '(-inf'}, {ub or 'inf)'}, got {v!r}")


@dataclasses.dataclass(frozen=True)
class SHACConfig:
    """SHAC hyperparameters; the defaults are the authors' cartpole swing-up config
    (``examples/cfg/shac/cartpole_swing_up.yaml`` in NVlabs/DiffRL; their names in brackets).

    task: one of :data:`TASKS_SHAC` ["shac_cartpole"], or "custom" with a task passed to :func:`make_trainer`.
    horizon: episode length in control steps, None = the task's own (240 for shac_cartpole) [episode_length].
    num_envs: parallel environments [num_actors = 64].
    short_horizon: steps per window, h [steps_num = 32].
    epochs: training epochs, one window each [max_epochs = 500].
    gamma: discount [0.99].
    lam: TD(lambda) parameter of the critic targets [lambda = 0.95].
    critic_iterations: passes over the window's data per epoch [16].
    critic_minibatches: contiguous minibatches per pass [num_batch = 4].
    target_alpha: target critic soft update ``target = alpha target + (1 - alpha) critic`` [target_critic_alpha = 0.2].
    actor_lr, critic_lr: initial Adam step sizes [1e-2, 1e-3], decayed linearly to lr_end [1e-5] (lr_schedule = linear).
    adam_b1, adam_b2, adam_eps: Adam's betas and epsilon [betas = (0.7, 0.95); PyTorch eps 1e-8].
    actor_grad_norm, critic_grad_norm: global gradient-norm clip, None = none [grad_norm = 1.0, truncate_grads].
    actor_units, critic_units: hidden widths of the ELU + LayerNorm MLPs [(64, 64), (64, 64)].
    init_log_std: initial state-independent log-std of the actor [actor_logstd_init = -1].
    normalize: running observation mean/std normalisation [obs_rms = True].
    bodies: "rods" (this library's) or "brax_v1" (the CE-APG authors' Brax v1 bodies) for a paper task
      (:func:`lagrange.tasks.make_task`); other tasks bring their own bodies (leave "rods").
    """

    task: str = "shac_cartpole"
    horizon: int | None = None
    num_envs: int = 64
    short_horizon: int = 32
    epochs: int = 500
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
    actor_units: tuple[int, ...] = (64, 64)
    critic_units: tuple[int, ...] = (64, 64)
    init_log_std: float = -1.0
    normalize: bool = True
    bodies: str = "rods"

    def __post_init__(self):
        if self.task not in TASKS_SHAC and self.task != "custom":
            raise ValueError(f"SHACConfig.task must be one of {sorted(TASKS_SHAC)} (or 'custom' with a task passed "
                             f"to make_trainer), got {self.task!r}")
        if self.bodies not in BODIES:
            raise ValueError(f"SHACConfig.bodies must be one of {list(BODIES)}, got {self.bodies!r}")
        if self.bodies != "rods" and self.task not in TASKS:
            raise ValueError(f"SHACConfig.bodies={self.bodies!r} is for the paper tasks {sorted(TASKS)}; "
                             f"task {self.task!r} brings its own bodies (leave bodies='rods')")
        if self.horizon is not None:
            _int("horizon", self.horizon, 1)
        _int("num_envs", self.num_envs, 1)
        _int("short_horizon", self.short_horizon, 1)
        _int("epochs", self.epochs, 1)
        _int("critic_iterations", self.critic_iterations, 0)
        _int("critic_minibatches", self.critic_minibatches, 1)
        if self.critic_minibatches > self.num_envs * self.short_horizon:
            raise ValueError(f"SHACConfig.critic_minibatches must be <= num_envs * short_horizon "
                             f"({self.num_envs * self.short_horizon}), got {self.critic_minibatches}")
        _real("gamma", self.gamma, 0, 1, lo_open=True)
        _real("lam", self.lam, 0, 1)
        _real("target_alpha", self.target_alpha, 0, 1)
        for name in ("actor_lr", "critic_lr", "lr_end", "adam_eps"):
            _real(name, getattr(self, name), 0, lo_open=True)
        _real("adam_b1", self.adam_b1, 0, 1, hi_open=True)
        _real("adam_b2", self.adam_b2, 0, 1, hi_open=True)
        for name in ("actor_grad_norm", "critic_grad_norm"):
            if getattr(self, name) is not None:
                _real(name, getattr(self, name), 0, lo_open=True)
        for name in ("actor_units", "critic_units"):
            units = getattr(self, name)
            if not isinstance(units, tuple) or not units or any(
                    isinstance(u, bool) or not isinstance(u, (int, np.integer)) or u < 1 for u in units):
                raise ValueError(f"SHACConfig.{name} must be a non-empty tuple of integers >= 1, got {units!r}")
        _real("init_log_std", self.init_log_std)
        if not isinstance(self.normalize, bool):
            raise ValueError(f"SHACConfig.normalize must be True or False, got {self.normalize!r}")

    def env_steps_per_epoch(self) -> int:
        return self.num_envs * self.short_horizon

    def learning_rates(self, epoch):
        """``(actor_lr, critic_lr)`` of epoch ``epoch`` (0-based): linear from the start value to ``lr_end``."""
        frac = jnp.asarray(epoch) / self.epochs
        return (self.actor_lr + (self.lr_end - self.actor_lr) * frac,
                self.critic_lr + (self.lr_end - self.critic_lr) * frac)
