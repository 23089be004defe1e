"""What every task is: a pure, immutable :class:`eqx.Module` over a chain.

A task is ``reset(key) -> state``, ``step(state, action) -> state``, ``observe(state) -> obs`` and
``reward(state, action, next_state) -> r`` (the reward of a transition is a function of the state it lands in, as in
Brax). Nothing is stored between calls, so every method can be ``jit``-ed, ``vmap``-ed and differentiated.

Conventions. The chains of :mod:`lagrange.systems` hang down at ``q = 0`` and use *relative* joint angles. The tasks
report angles wrapped to ``(-pi, pi]`` with 0 meaning upright for the first pole (``th1 = wrap(q1 - pi)``) and
straight for later links (``th2 = wrap(q2)``). Actions ``a`` are clipped to ``[-1, 1]`` and multiplied by the
chain's gear. A cart, where there is one, is ``q[0]``; the poles follow it (``first_pole``).
"""

import abc
from typing import NamedTuple

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar, AbstractVar
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from lagrange.chain import Chain
from lagrange.integrate import step as _step
from lagrange.solvers import SemiImplicitEuler, SymplecticEuler

__all__ = ["TaskState", "AbstractTask", "control_step", "wrap"]

_Solver = diffrax.AbstractSolver | SemiImplicitEuler | SymplecticEuler
"""The solvers a task steps with (:mod:`lagrange.solvers`; any explicit diffrax Runge-Kutta solver)."""


def wrap(angle: Float[ArrayLike, " *shape"]) -> Float[Array, " *shape"]:
    """Wrap angles [rad] to ``(-pi, pi]``, elementwise."""
    return jnp.pi - jnp.mod(jnp.pi - angle, 2 * jnp.pi)


class TaskState(NamedTuple):
    """Generalized coordinates ``q`` (n,) and velocities ``qd`` (n,) of the chain (rad and rad/s; m and m/s for a
    cart)."""

    q: Float[Array, " n"]
    qd: Float[Array, " n"]


class AbstractTask(eqx.Module):
    """A control task on a planar chain; every method is pure.

    Subclasses provide the fields ``chain``, ``dt`` (the control interval [s]), ``horizon`` (control steps per
    episode), ``substeps`` and ``solver`` (``substeps`` steps of ``solver`` per interval), the class variables
    ``first_pole`` (the index in ``q`` of the first pole's joint: 1 after a cart, else 0) and ``name`` (a display
    name for titles and results, never switched on), and ``reset``, ``observe``, ``reward`` and
    ``observation_size``. The dynamics (``step``) and the angle readings are the same for every task.
    """

    chain: AbstractVar[Chain]
    dt: AbstractVar[float]
    horizon: AbstractVar[int]
    substeps: AbstractVar[int]
    solver: AbstractVar[_Solver]
    first_pole: AbstractClassVar[int]
    name: AbstractClassVar[str]

    @abc.abstractmethod
    def reset(self, key: PRNGKeyArray) -> TaskState:
        """A random start state drawn with ``key``."""

    @abc.abstractmethod
    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """The observation vector of ``state``."""

    @abc.abstractmethod
    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """Reward of the transition ``state --action--> next_state``."""

    @property
    @abc.abstractmethod
    def observation_size(self) -> int:
        """Length of :meth:`observe`'s vector."""

    # -- concrete -------------------------------------------------------------------------------
    @property
    def action_size(self) -> int:
        """Number of actions: the chain's actuated joints ``chain.m``."""
        return self.chain.m

    @property
    def cart(self) -> bool:
        """Whether ``q[0]`` is a prismatic cart coordinate (``first_pole == 1``)."""
        return self.first_pole == 1

    @property
    def n_links(self) -> int:
        """Number of poles (revolute links)."""
        return self.chain.n - self.first_pole

    def step(self, state: TaskState, action: Float[ArrayLike, " m"]) -> TaskState:
        """One control interval ``dt`` under ``clip(action, -1, 1)`` times the chain's gear (:func:`control_step`)."""
        return control_step(self, state, action)

    def angles(self, state: TaskState) -> Float[Array, " n_links"]:
        """Pole angles (n_links,) [rad], wrapped, 0 = first pole upright / later links straight."""
        rel = state.q[self.first_pole:]
        offset = jnp.zeros_like(rel).at[0].set(jnp.pi)
        return wrap(rel - offset)

    def link_angles(self, state: TaskState) -> Float[Array, " n_links"]:
        """Absolute pole orientations (n_links,) [rad], wrapped, 0 = pointing straight up."""
        return _link_angles(self, state.q)

    def angular_velocities(self, state: TaskState) -> Float[Array, " n_links"]:
        """Joint velocities of the poles (n_links,) [rad/s], relative as the angles are."""
        return state.qd[self.first_pole:]


def control_step(task: AbstractTask, state: TaskState, action: Float[ArrayLike, " m"]) -> TaskState:
    """One control interval ``task.dt`` (``task.substeps`` solver steps of ``task.solver``) under
    ``clip(action, -1, 1)`` times the chain's gear; the ``step`` of every task."""
    a = jnp.clip(action, -1.0, 1.0)
    q, qd = _step(task.chain, state.q, state.qd, a, task.dt, task.solver, task.substeps)
    return TaskState(q, qd)


def _link_angles(task: AbstractTask, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n_links"]:
    rel = q[..., task.first_pole:]
    return wrap(jnp.cumsum(rel, axis=-1) - jnp.pi)


def _check_schedule(task: AbstractTask) -> None:
    """``dt``, ``horizon`` and ``substeps`` in range, or a ``ValueError`` naming the field."""
    cls = type(task).__name__
    for field in ("horizon", "substeps"):
        v = getattr(task, field)
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{cls}.{field} must be an integer >= 1, got {v!r}")
    if not task.dt > 0:
        raise ValueError(f"{cls}.dt must be > 0 (seconds), got {task.dt!r}")


def _check_joints(task: AbstractTask, joints: tuple[str, ...]) -> None:
    """The chain's joint kinds are ``joints`` and it has a motor, or a ``ValueError``."""
    cls = type(task).__name__
    if tuple(task.chain.joints) != joints:
        raise ValueError(f"{cls}.chain must have the joints {joints}, got {task.chain.joints}")
    if task.chain.m < 1:
        raise ValueError(f"{cls}.chain must be actuated (some link with a gear), got chain.m=0")
