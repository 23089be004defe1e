"""Control tasks on exact chains: the CE-APG paper's swing-ups and the SHAC authors' cartpole.

A task is an immutable :class:`equinox.Module` with pure methods ``reset(key)``, ``step(state, action)``,
``observe(state)`` and ``reward(state, action, next_state)`` (:class:`AbstractTask`, in :mod:`lagrange.tasks.base`):

- :class:`Acrobot`, :class:`Cartpole` and :class:`DoubleCartpole`, the CE-APG paper's swing-ups, built on this
  library's rods (``Acrobot.rods()``) or on the authors' Brax v1 bodies (``Acrobot.brax_v1()``), and
  :class:`ChainSwingup` for a revolute chain of one's own (:mod:`lagrange.tasks.swingup`, with the integrator's error
  table); :data:`PAPER_TASKS` names the paper's three, :data:`BODY_SETS` their constructors.
- :class:`DiffRLCartpole`, the SHAC authors' environment, NVlabs/DiffRL (:mod:`lagrange.tasks.diffrl_cartpole`).
- :class:`Hopper` and :class:`Cheetah`, the SHAC paper's planar locomotion as DFlex runs it (``.diffrl()``;
  :mod:`lagrange.tasks.locomotion`), and :class:`Ant` and :class:`Humanoid`, its 3-D ones
  (:mod:`lagrange.tasks.locomotion3d`): every one an :class:`AbstractLocomotion` (DFlex's robot, the noisy start,
  the action cost, the gait's track), planar (:class:`AbstractPlanarLocomotion`) or 3-D
  (:class:`AbstractLocomotion3D`); :class:`SNUHumanoid`, its muscle-actuated humanoid (:mod:`lagrange.tasks.snu`,
  on MASS's model, :mod:`lagrange.tasks.snu_tree`).
- :func:`balanced`, :func:`upright_error` and :func:`leaves_upright` judge an episode
  (:mod:`lagrange.tasks.poles`, with :class:`AbstractPoleTask`).

Each final class documents its state, action, observation and reward in a table.
"""

from lagrange.tasks.base import AbstractTask, TaskState, control_step, wrap
from lagrange.tasks.poles import AbstractPoleTask, balanced, leaves_upright, upright_error
from lagrange.tasks.diffrl_cartpole import POLE_INERTIA, DiffRLCartpole
from lagrange.tasks.locomotion import AbstractLocomotion, AbstractPlanarLocomotion, Cheetah, Hopper
from lagrange.tasks.locomotion3d import AbstractLocomotion3D, Ant, Humanoid
from lagrange.tasks.snu import SNUHumanoid
from lagrange.tasks.swingup import (
    BODY_SETS,
    PAPER_TASKS,
    AbstractPaperSwingup,
    AbstractSwingup,
    Acrobot,
    Cartpole,
    ChainSwingup,
    DoubleCartpole,
)

__all__ = [
    "AbstractTask",
    "AbstractPoleTask",
    "TaskState",
    "control_step",
    "wrap",
    "AbstractSwingup",
    "AbstractPaperSwingup",
    "Acrobot",
    "Cartpole",
    "DoubleCartpole",
    "ChainSwingup",
    "PAPER_TASKS",
    "BODY_SETS",
    "DiffRLCartpole",
    "AbstractLocomotion",
    "AbstractPlanarLocomotion",
    "Hopper",
    "Cheetah",
    "AbstractLocomotion3D",
    "Ant",
    "Humanoid",
    "SNUHumanoid",
    "POLE_INERTIA",
    "balanced",
    "leaves_upright",
    "upright_error",
]
