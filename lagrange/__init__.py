"""lagrange: exact, fast, differentiable dynamics of kinematic trees in pure JAX: planar chains and trees (with ground
contact and joint limits by penalty forces) and spatial trees of hinges, slides, balls and free joints."""

from lagrange.chain import Chain, Link
from lagrange.joints import Ball, Free, Hinge, Slide
from lagrange.tree import Body, Motor, Tree
from lagrange.contact import PenaltyContact
from lagrange.limits import PenaltyLimits
from lagrange.actuation import actuation_matrix, clamp_controls
from lagrange.dynamics import (
    bias_forces,
    energy,
    forward_dynamics,
    gravity_forces,
    inverse_dynamics,
    mass_matrix,
)
from lagrange.integrate import Trajectory, simulate, step
from lagrange.batch import simulate_batch
from lagrange.compile import compiler_options
from lagrange.kinematics import com_positions, positions
from lagrange.precision import astype
from lagrange.solvers import RK4, Dopri5, Dopri8, Euler, MomentumEuler, SemiImplicitEuler, Tsit5
from lagrange import solvers, systems

__all__ = [
    "Ball",
    "Body",
    "Free",
    "Hinge",
    "Motor",
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
    "positions",
]


def __getattr__(name: str) -> type:
    """The renamed solvers' old names (:data:`lagrange.solvers.RENAMED`), with a ``DeprecationWarning``."""
    return solvers.renamed(name)
