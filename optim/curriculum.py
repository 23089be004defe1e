"""CE-APG's training curriculum: what candidates train and are scored on besides the task itself (starts upright,
wider start noise, shorter warm-up episodes), as one typed object (:class:`Curriculum`).

:class:`optim.CEAPGConfig` keeps the five settings as flat fields (``config.upright_starts``, ...), so that a config,
its JSON form in checkpoints and results and the ``--set warmup_horizons=300,400`` overrides of the benchmarks stay as
they were; ``config.curriculum`` is the :class:`Curriculum` they make, which holds the stage logic.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Int

from lagrange.tasks import AbstractTask
from optim.validate import check_int, check_positive, check_probability

__all__ = ["Curriculum", "check_curriculum"]


def check_curriculum(cls: str, settings) -> None:
    """Check the five curriculum settings of ``settings`` (a :class:`Curriculum` or a config with the same fields),
    turning ``warmup_horizons`` into a tuple.

    Args:
        cls: the class name the errors give (``"CEAPGConfig"``, ``"Curriculum"``).
        settings: the object whose fields are checked.

    Raises:
        ValueError: naming ``cls.field`` and what it allows.
    """
    check_probability(cls, "upright_starts", settings.upright_starts)
    if settings.train_noise is not None:
        check_positive(cls, "train_noise", settings.train_noise, allow_zero=True)
    horizons = settings.warmup_horizons
    if isinstance(horizons, (str, bytes)) or not hasattr(horizons, "__iter__"):
        raise ValueError(f"{cls}.warmup_horizons must be a sequence of integers >= 1, got {horizons!r}")
    object.__setattr__(settings, "warmup_horizons", tuple(horizons))
    for i, h in enumerate(settings.warmup_horizons):
        check_int(cls, f"warmup_horizons[{i}]", h, 1)
    check_int(cls, "warmup_iterations", settings.warmup_iterations, 1)
    check_probability(cls, "warmup_upright", settings.warmup_upright)


@dataclasses.dataclass(frozen=True)
class Curriculum:
    """The episodes CE-APG's candidates train and are scored on, where they differ from the task's own; what is
    evaluated (``Trainer.task``) is always the task as given. The defaults are no curriculum (the paper's).

    The first ``len(warmup_horizons) * warmup_iterations`` iterations are the warm-up: stage ``i`` trains on episodes
    of ``warmup_horizons[i]`` control steps for ``warmup_iterations`` iterations, starting upright with probability
    ``warmup_upright``; the rest train on the task's horizon, starting upright with probability ``upright_starts``.

    Attributes:
        upright_starts (float): probability in [0, 1] that a training episode after the warm-up starts balanced
            upright instead of hanging (paper: 0). Needs a task with an ``upright`` field.
        train_noise (float | None): half-width >= 0 of the uniform noise on every angle [rad] and velocity [rad/s]
            at the start of every training episode, warm-up included; None keeps the task's ``noise`` (paper: None).
            Needs a task with a ``noise`` field.
        warmup_horizons (tuple[int, ...]): the warm-up's episode lengths in control steps, each >= 1 (paper: none).
        warmup_iterations (int): iterations of each warm-up stage, >= 1.
        warmup_upright (float): probability in [0, 1] that a warm-up episode starts upright.
    """

    upright_starts: float = 0.0
    train_noise: float | None = None
    warmup_horizons: tuple[int, ...] = ()
    warmup_iterations: int = 15
    warmup_upright: float = 1.0

    def __post_init__(self):
        check_curriculum(type(self).__name__, self)

    @property
    def stages(self) -> int:
        """The number of warm-up stages, ``len(warmup_horizons)``."""
        return len(self.warmup_horizons)

    @property
    def warmup_length(self) -> int:
        """Iterations of the whole warm-up, ``stages * warmup_iterations``."""
        return self.stages * self.warmup_iterations

    def stage(self, iteration: Int[ArrayLike, ""]) -> Int[Array, ""]:
        """The stage of an iteration: ``i < stages`` trains on ``warmup_horizons[i]``, ``stages`` on the task.

        Args:
            iteration: the 0-based iteration, an int or a traced integer.
        """
        return jnp.minimum(iteration // self.warmup_iterations, self.stages)

    def training_horizon(self, iteration: int, horizon: int) -> int:
        """The episode length [control steps] candidates train on: a warm-up horizon, then the task's.

        Args:
            iteration: the 0-based iteration.
            horizon: the task's episode length in control steps.
        """
        return (*self.warmup_horizons, horizon)[int(self.stage(iteration))]

    def compressed(self, planned: int, iterations: int) -> Curriculum:
        """The same curriculum for a shorter or longer run: each warm-up stage keeps its share
        (``warmup_iterations * iterations // planned``), and the warm-up is dropped when that is less than one.

        Args:
            planned: the iterations the curriculum was made for.
            iterations: the run's iterations.
        """
        if not self.warmup_horizons:
            return self
        per_stage = self.warmup_iterations * iterations // planned
        if per_stage >= 1:
            return dataclasses.replace(self, warmup_iterations=per_stage)
        return dataclasses.replace(self, warmup_horizons=())

    def tasks(self, task: AbstractTask, *, owner: str = "Curriculum") -> list[AbstractTask]:
        """The tasks candidates train and are scored on, one per stage: the warm-up horizons (starting upright with
        probability ``warmup_upright``), then ``task`` itself with ``upright_starts``; all with ``train_noise``.

        Args:
            task: the task as given (a swing-up of :mod:`lagrange.tasks` where the curriculum sets a field).
            owner: the class name the error gives.

        Raises:
            ValueError: if the curriculum needs a ``noise`` or ``upright`` field the task lacks.
        """
        for name, wanted in (("noise", self.train_noise is not None),
                             ("upright", self.upright_starts > 0 or bool(self.warmup_horizons))):
            if wanted and not hasattr(task, name):
                raise ValueError(f"{owner}: the curriculum needs a task with a {name!r} field (the swing-ups of "
                                 f"lagrange.tasks); {type(task).__name__} has none. Leave train_noise=None, "
                                 f"upright_starts=0 and warmup_horizons=() for this task")
        noisy = task if self.train_noise is None else dataclasses.replace(task, noise=float(self.train_noise))
        train_task = dataclasses.replace(noisy, upright=self.upright_starts) if self.upright_starts else noisy
        stages = [dataclasses.replace(noisy, horizon=h, upright=self.warmup_upright) for h in self.warmup_horizons]
        return stages + [train_task]
