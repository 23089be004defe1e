"""lagrange: exact, fast, differentiable dynamics of kinematic trees in pure JAX: planar chains and trees (with ground
contact and joint limits by penalty forces) and spatial trees of hinges, slides, balls and free joints."""

import importlib
import sys

from lagrange.chain import Chain, Link
from lagrange.model.joints import Ball, Free, Hinge, Slide
from lagrange.model.tree import AffineActuator, Body, Motor, Tree
from lagrange.model.muscles import Muscle
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits
from lagrange.forces import actuation_matrix, clamp_controls
from lagrange.dynamics import (
    bias_forces,
    energy,
    forward_dynamics,
    gravity_forces,
    inverse_dynamics,
    mass_matrix,
)
from lagrange.integrate import Trajectory, simulate, step
from lagrange.integrate.batch import simulate_batch
from lagrange.compile import compiler_options
from lagrange.kinematics import com_positions, muscle_lengths, positions
from lagrange.precision import astype
from lagrange.integrate.solvers import RK4, Dopri5, Dopri8, Euler, MomentumEuler, SemiImplicitEuler, Tsit5
from lagrange.integrate import solvers
from lagrange import systems

__all__ = [
    "Ball",
    "Body",
    "Free",
    "Hinge",
    "Motor",
    "AffineActuator",
    "Muscle",
    "Slide",
    "Tree",
    "RK4",
    "Dopri5",
    "Dopri8",
    "Euler",
    "SemiImplicitEuler",
    "MomentumEuler",
    "Tsit5",
    "Trajectory",
    "compiler_options",
    "simulate",
    "simulate_batch",
    "step",
    "systems",
    "Chain",
    "Link",
    "PenaltyContact",
    "PenaltyLimits",
    "actuation_matrix",
    "astype",
    "clamp_controls",
    "bias_forces",
    "com_positions",
    "energy",
    "forward_dynamics",
    "gravity_forces",
    "inverse_dynamics",
    "mass_matrix",
    "muscle_lengths",
    "positions",
]


# the modules' homes before the layout of model/, integrate/, planar/ and rbda/: ``import lagrange.tree`` and the rest
# still find them
_MOVED = {"tree": "lagrange.model.tree", "joints": "lagrange.model.joints", "contact": "lagrange.model.contact",
          "limits": "lagrange.model.limits", "checks": "lagrange.model.checks", "solvers": "lagrange.integrate.solvers",
          "batch": "lagrange.integrate.batch"}
for _old, _new in _MOVED.items():
    sys.modules[f"lagrange.{_old}"] = globals()[_old] = importlib.import_module(_new)


def __getattr__(name: str) -> type:
    """The renamed solvers' old names (:data:`lagrange.integrate.solvers.RENAMED`), with a ``DeprecationWarning``."""
    return solvers.renamed(name)
