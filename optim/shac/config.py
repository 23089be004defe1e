"""SHAC's typed configuration: the authors' cartpole-swing-up settings by default."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from optim.base import AlgorithmConfig
from optim.shac.trainer import make_trainer
from optim.validate import check_bool, check_int, check_real

__all__ = ["SHACConfig"]


@dataclasses.dataclass(frozen=True)
class SHACConfig(AlgorithmConfig):
    """SHAC settings; the defaults are the authors' cartpole swing-up config
    (``examples/cfg/shac/cartpole_swing_up.yaml`` in NVlabs/DiffRL; their names and values below). The task (its
    ``horizon`` is the authors' ``episode_length``) and the actor (:class:`policies.Actor`, their ``actor_mlp`` units
    and ``actor_logstd_init``) are passed to :func:`optim.train`, not set here.

    Attributes:
        num_envs (int): parallel environments, >= 1 (authors: num_actors = 64).
        short_horizon (int): control steps per window, h, >= 1 (authors: steps_num = 32).
        iterations (int): training epochs, one window each, >= 1 (authors: max_epochs = 500).
        gamma (float): discount, in (0, 1] (authors: 0.99).
        lam (float): TD(lambda) parameter of the critic targets, in [0, 1] (authors: lambda = 0.95).
        critic_iterations (int): passes over the window's data per epoch, >= 0 (authors: 16).
        critic_minibatches (int): contiguous minibatches per pass, 1 <= critic_minibatches <= num_envs *
            short_horizon (authors: num_batch = 4).
        target_alpha (float): the target critic's soft update ``target = alpha target + (1 - alpha) critic``, in
            [0, 1] (authors: target_critic_alpha = 0.2).
        actor_lr (float): the actor's initial Adam step size, > 0, decayed linearly to ``lr_end`` (authors: 1e-2,
            lr_schedule = linear).
        critic_lr (float): the critic's, > 0 (authors: 1e-3).
        lr_end (float): both step sizes at the last epoch, > 0 (authors: 1e-5).
        adam_b1 (float): Adam's first beta, in [0, 1) (authors: 0.7).
        adam_b2 (float): Adam's second beta, in [0, 1) (authors: 0.95).
        adam_eps (float): Adam's epsilon, > 0 (authors: PyTorch's 1e-8).
        actor_grad_norm (float | None): the actor gradient's global-norm clip (PyTorch's ``clip_grad_norm_``), > 0;
            None: none (authors: grad_norm = 1.0, truncate_grads).
        critic_grad_norm (float | None): the critic gradient's (authors: 1.0).
        critic_units (tuple[int, ...]): hidden widths of the critic's ELU + LayerNorm MLP, each >= 1 (authors:
            critic_mlp (64, 64)).
        normalize (bool): running observation mean/std normalisation (authors: obs_rms = True).
        use_critic (bool): False: no critic is trained and the actor's loss is the window's discounted reward alone
            (no terminal value): the authors' BPTT baseline (``algorithms/bptt.py``, see :meth:`bptt`).
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
    use_critic: bool = True

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
        check_bool(c, "use_critic", self.use_critic)

    @classmethod
    def hopper(cls, **overrides) -> "SHACConfig":
        """The authors' hopper config (``examples/cfg/shac/hopper.yaml``): 256 envs, 2000 epochs (16.4M env steps),
        actor lr 2e-3, critic lr 2e-4; the rest as the defaults. The actor is ``policies.Actor.for_task(task,
        units=(128, 64, 32))``. ``overrides`` replace fields.
        """
        return dataclasses.replace(cls(num_envs=256, iterations=2000, actor_lr=2e-3, critic_lr=2e-4), **overrides)

    @classmethod
    def cheetah(cls, **overrides) -> "SHACConfig":
        """The authors' cheetah config (``examples/cfg/shac/cheetah.yaml``): 64 envs, 2000 epochs (4.1M env steps),
        actor and critic lr 2e-3; the rest as the defaults. The actor is ``policies.Actor.for_task(task,
        units=(128, 64, 32))``. ``overrides`` replace fields.
        """
        return dataclasses.replace(cls(num_envs=64, iterations=2000, actor_lr=2e-3, critic_lr=2e-3), **overrides)

    @classmethod
    def ant(cls, **overrides) -> "SHACConfig":
        """The authors' ant config (``examples/cfg/shac/ant.yaml``): 64 envs, 2000 epochs (4.1M env steps), actor and
        critic lr 2e-3, target alpha 0.2; the rest as the defaults (the cheetah's settings). The actor is
        ``policies.Actor.for_task(task, units=(128, 64, 32))``. ``overrides`` replace fields.
        """
        return dataclasses.replace(cls(num_envs=64, iterations=2000, actor_lr=2e-3, critic_lr=2e-3), **overrides)

    @classmethod
    def humanoid(cls, **overrides) -> "SHACConfig":
        """The authors' humanoid config (``examples/cfg/shac/humanoid.yaml``): 64 envs, 2000 epochs (4.1M env
        steps), actor lr 2e-3, critic lr 5e-4, target alpha 0.995, critic (128, 128); the rest as the defaults. The
        actor is ``policies.Actor.for_task(task, units=(256, 128))``. ``overrides`` replace fields.
        """
        return dataclasses.replace(cls(num_envs=64, iterations=2000, actor_lr=2e-3, critic_lr=5e-4,
                                       target_alpha=0.995, critic_units=(128, 128)), **overrides)

    @classmethod
    def snu_humanoid(cls, **overrides) -> "SHACConfig":
        """The authors' SNU humanoid config (``examples/cfg/shac/snu_humanoid.yaml``): the humanoid's (:meth:`humanoid`)
        with a critic of (256, 256). The actor is ``policies.Actor.for_task(task, units=(512, 256))``. ``overrides``
        replace fields.
        """
        return cls.humanoid(**{"critic_units": (256, 256), **overrides})

    @classmethod
    def bptt(cls, task: str, **overrides) -> "SHACConfig":
        """The SHAC paper's BPTT baseline as its authors ran it (``examples/cfg/bptt/<task>.yaml``): no critic, windows
        in 32 environments that continue across epochs, 2000 epochs, the actor's lr decayed linearly, the same Adam
        betas, gradient clip and observation normalisation as SHAC. Windows of 128 steps (hopper, cheetah: 8.2M env
        steps) or of a whole episode, 1000 steps (ant, humanoid: 64M; the SNU humanoid's in 16 environments: 32M);
        actor lr 1e-3 (hopper), 2e-3 (cheetah, humanoids) or 4e-3 (ant).

        Args:
            task: ``"hopper"``, ``"cheetah"``, ``"ant"``, ``"humanoid"`` or ``"snu_humanoid"``.
            overrides: fields to replace.

        Raises:
            ValueError: for another task name.
        """
        settings = {"hopper": (128, 1e-3, 32), "cheetah": (128, 2e-3, 32), "ant": (1000, 4e-3, 32),
                    "humanoid": (1000, 2e-3, 32), "snu_humanoid": (1000, 2e-3, 16)}
        if task not in settings:
            raise ValueError(f"SHACConfig.bptt: task must be one of {sorted(settings)}, got {task!r}")
        window, lr, envs = settings[task]
        return dataclasses.replace(cls(num_envs=envs, short_horizon=window, iterations=2000, actor_lr=lr,
                                       critic_iterations=0, use_critic=False), **overrides)

    def env_steps_per_epoch(self) -> int:
        """Simulated control steps of one epoch, ``num_envs * short_horizon``."""
        return self.num_envs * self.short_horizon

    def learning_rates(self, epoch):
        """The learning rates of an epoch, linear from their start values to ``lr_end``.

        Args:
            epoch: the 0-based epoch, an int or a traced integer.

        Returns:
            ``(actor_lr, critic_lr)``.
        """
        frac = jnp.asarray(epoch) / self.iterations
        return (self.actor_lr + (self.lr_end - self.actor_lr) * frac,
                self.critic_lr + (self.lr_end - self.critic_lr) * frac)

    def make_trainer(self, task, policy, *, objective: Callable | None = None):
        """:func:`optim.shac.make_trainer` of this config.

        Args:
            task: the task to train on, and the one the trainer evaluates.
            policy: the actor, a :class:`policies.Actor` (SHAC draws its initial weights with ``reinit``).
            objective: must be None: SHAC's actor loss is its own.

        Raises:
            ValueError: for an ``objective``.
        """
        if objective is not None:
            raise ValueError("SHAC has its own actor loss: objective must be None")
        return make_trainer(self, task, policy)
