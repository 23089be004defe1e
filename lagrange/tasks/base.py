"""What every task is: a pure, immutable :class:`eqx.Module` over a chain.

A task is ``reset(key) -> state``, ``step(state, action) -> state``, ``observe(state) -> obs``,
``reward(state, action, next_state) -> r`` (the reward of a transition is a function of the state it lands in, as in
Brax) and ``terminated(state)`` (an episode that ends early, a hopper that fell). Nothing is stored between calls, so
every method can be ``jit``-ed, ``vmap``-ed and differentiated. Actions ``a`` are clipped to ``[-1, 1]`` and
multiplied by the chain's gear.

The pole tasks (the swing-ups, the SHAC authors' cartpole) are :class:`lagrange.tasks.poles.AbstractPoleTask`s.
"""

import abc
import math
from typing import ClassVar, NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar, AbstractVar
from jaxtyping import Array, ArrayLike, Bool, Float, PRNGKeyArray

from lagrange.integrate import step as _step
from lagrange.model.joints import Hinge, Slide
from lagrange.integrate.interval import check_solver
from lagrange.integrate.solvers import MomentumEuler, SemiImplicitEuler
from lagrange.model.tree import Tree, check_tree

__all__ = ["TaskState", "AbstractTask", "TaskSolver", "control_step", "wrap",
           "check_schedule", "check_joints", "check_number", "check_state", "check_chain", "joint_kinds"]

TaskSolver = diffrax.AbstractSolver | SemiImplicitEuler | MomentumEuler
"""The solvers a task steps with (:mod:`lagrange.integrate.solvers`; any explicit diffrax Runge-Kutta solver)."""


def wrap(angle: Float[ArrayLike, " *shape"]) -> Float[Array, " *shape"]:
    """Wrap angles to ``(-pi, pi]``, elementwise.

    Args:
        angle: angles [rad], any shape.
    """
    return jnp.pi - jnp.mod(jnp.pi - angle, 2 * jnp.pi)


class TaskState(NamedTuple):
    """A task's state: the chain's generalized coordinates and velocities, and for a task that observes it, the
    action last applied.

    Attributes:
        q (Float[Array, "nq"]): coordinates [rad; m for a cart] (``nq = nv``, one per joint, for a chain; a ball
            or a free joint has a quaternion among them).
        qd (Float[Array, "nv"]): velocities [rad/s; m/s for a cart].
        action (Float[Array, "m"] | None): the clipped action of the step that reached the state (zeros at a reset),
            for tasks that observe it (DFlex's Ant and Humanoid); None for the others. :func:`control_step` keeps it
            up to date when it is not None.
    """

    q: Float[Array, " nq"]
    qd: Float[Array, " nv"]
    action: Float[Array, " m"] | None = None


class AbstractTask(eqx.Module):
    """A control task on a planar chain or tree or a spatial tree; every method is pure. Subclasses provide the fields
    and class variables below, and ``reset``, ``observe``, ``reward`` and ``observation_size``; the dynamics
    (``step``) are the same for every task.

    Attributes:
        chain (Tree): the robot (a :class:`lagrange.chain.Chain` is one).
        dt (float): the control interval [s].
        horizon (int): control steps per episode.
        substeps (int): steps of ``solver`` per control interval.
        solver (TaskSolver): the integrator (:mod:`lagrange.integrate.solvers`, or an explicit diffrax Runge-Kutta
        solver). name (ClassVar[str]): a display name for titles and results, never switched on.
    """

    chain: AbstractVar[Tree]
    dt: AbstractVar[float]
    horizon: AbstractVar[int]
    substeps: AbstractVar[int]
    solver: AbstractVar[TaskSolver]
    name: AbstractClassVar[str]

    @abc.abstractmethod
    def reset(self, key: PRNGKeyArray) -> TaskState:
        """A random start state.

        Args:
            key: the PRNG key it is drawn with.
        """

    @abc.abstractmethod
    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """The observation vector of a state, shape ``(observation_size,)``.

        Args:
            state: the state.
        """

    @abc.abstractmethod
    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """The reward of a transition ``state --action--> next_state``, a scalar (each task's docstring gives its
        formula; the arguments are these).

        Args:
            state: the state before.
            action: the action, shape ``(m,)``.
            next_state: the state after.
        """

    @property
    @abc.abstractmethod
    def observation_size(self) -> int:
        """Length of :meth:`observe`'s vector."""

    # -- concrete -------------------------------------------------------------------------------
    @property
    def action_size(self) -> int:
        """Number of actions: the chain's actuated joints ``chain.m``."""
        return self.chain.m

    def controls(self, action: Float[Array, " m"]) -> Float[Array, " m"]:
        """The chain's controls ``u`` for a clipped action (in ``[-1, 1]``): the action itself, the chain's gears
        turning it into torques; a task whose controls are not torques maps it (the SNU humanoid's muscle
        activations ``a / 2 + 1/2`` in ``[0, 1]``).

        Args:
            action: one action, clipped, shape ``(m,)``.
        """
        return action

    def step(self, state: TaskState, action: Float[ArrayLike, " m"]) -> TaskState:
        """One control interval ``dt`` under ``clip(action, -1, 1)`` times the chain's gear (:func:`control_step`).

        Args:
            state: one state.
            action: one action, shape ``(m,)``.
        """
        return control_step(self, state, action)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "terminated" in cls.__dict__ and not cls.ends_early:
            raise TypeError(f"{cls.__name__} defines terminated but not ends_early = True: set the class variable "
                            "ends_early: ClassVar[bool] = True, or the rollouts never look at terminated")

    ends_early: ClassVar[bool] = False
    """Whether an episode can end early (:meth:`terminated`); static, so that the rollouts of a task that cannot
    (every pole task) trace no termination logic at all: masks that change nothing still change XLA's fusion of the
    rollout and with it the round-off, which a chaotic swing-up amplifies (the CE-APG acrobot demo's return moved
    from 2534 to 2040 when they were traced)."""

    def terminated(self, state: TaskState) -> Bool[Array, ""]:
        """Whether an episode ends early in ``state`` (after the transition that reached it, whose reward counts);
        never, unless a task says otherwise (and sets :attr:`ends_early`).

        Args:
            state: one state (``jax.vmap`` over a batch).
        """
        return jnp.zeros((), bool)

    def succeeded(self, q: Float[ArrayLike, "*batch T n"]) -> Bool[Array, " *batch"]:
        """Whether an episode met the task's goal, judged on its coordinates ``q`` (shape ``(*batch, T, n)``): here,
        that it never terminated early; a task with a goal of its own says what (the pole tasks: balanced at the end,
        :func:`lagrange.tasks.poles.balanced`).

        Args:
            q: a trajectory of coordinates, shape ``(*batch, T, n)``.
        """
        q = jnp.asarray(q)
        zeros = jnp.zeros_like(q)
        ended = jax.vmap(lambda qi, qdi: self.terminated(TaskState(qi, qdi)))(q.reshape(-1, q.shape[-1]),
                                                                              zeros.reshape(-1, q.shape[-1]))
        return ~jnp.any(ended.reshape(q.shape[:-1]), axis=-1)


def control_step(task: AbstractTask, state: TaskState, action: Float[ArrayLike, " m"]) -> TaskState:
    """One control interval ``task.dt`` (``task.substeps`` solver steps of ``task.solver``) under the controls
    ``task.controls(clip(action, -1, 1))`` (the clipped action itself, times the chain's gears, for most tasks); the
    ``step`` of every task.

    Args:
        task: the task.
        state: one state, ``q`` of shape ``(nq,)`` and ``qd`` of shape ``(nv,)``.
        action: one action, shape ``(m,)`` (``m = task.action_size``), dimensionless; integers are converted.

    Returns:
        The state one interval later.

    Raises:
        ValueError: for a state or an action of another shape (a batch: ``jax.vmap`` the step over it).
        TypeError: for a boolean or complex action.
    """
    m, cls = task.chain.m, type(task).__name__
    check_state(task, state, "step")
    if jnp.shape(action) != (m,):
        raise ValueError(f"{cls}.step: action must have shape (m,) = ({m},), one entry per actuated joint, got "
                         f"{jnp.shape(action)}; jax.vmap the step over a batch of actions")
    kind = jnp.result_type(action)
    if kind == jnp.bool_ or jnp.issubdtype(kind, jnp.complexfloating):
        raise TypeError(f"{cls}.step: action must hold real numbers in [-1, 1], got dtype {kind}")
    a = jnp.clip(action, -1.0, 1.0)
    q, qd = _step(task.chain, state.q, state.qd, task.controls(a), task.dt, task.solver, task.substeps)
    return TaskState(q, qd, None if state.action is None else a.astype(state.action.dtype))


def check_state(task: AbstractTask, state: TaskState, method: str | None = None) -> None:
    """Check that ``state`` is one :class:`TaskState` of the task's chain (a batch goes through ``jax.vmap``).

    Args:
        task: the task.
        state: the state.
        method: the method the error names, if any.

    Raises:
        TypeError: for something else than a ``TaskState``.
        ValueError: for ``q`` or ``qd`` of another shape than ``(nq,)`` and ``(nv,)``.
    """
    where, nq, nv = type(task).__name__ + (f".{method}" if method else ""), task.chain.nq, task.chain.nv
    if not isinstance(state, TaskState):
        raise TypeError(f"{where}: state must be a lagrange.tasks.TaskState(q, qd), got {type(state).__name__}")
    if jnp.shape(state.q) != (nq,) or jnp.shape(state.qd) != (nv,):
        want = f"shape (n,) = ({nv},)" if nq == nv else f"shapes (nq,) = ({nq},) and (nv,) = ({nv},)"
        raise ValueError(f"{where}: state.q and state.qd must have {want}, got {jnp.shape(state.q)} and "
                         f"{jnp.shape(state.qd)}; jax.vmap over a batch of states")
    if state.action is not None and jnp.shape(state.action) != (task.chain.m,):
        raise ValueError(f"{where}: state.action must have shape (m,) = ({task.chain.m},) or be None, got "
                         f"{jnp.shape(state.action)}")


def check_chain(task: AbstractTask, planar: bool = True) -> None:
    """Check that a task's ``chain`` is a :class:`lagrange.Tree` (a :class:`lagrange.chain.Chain` is one) and, with
    ``planar``, a planar one (:attr:`lagrange.Tree.planar`: the pole and planar locomotion tasks read its angles).

    Args:
        task: the task.
        planar: whether the tree must move in a plane.

    Raises:
        TypeError: naming the field and what it got.
    """
    check_tree(task.chain, f"{type(task).__name__}.chain")
    if planar and not task.chain.planar:
        raise TypeError(f"{type(task).__name__}.chain must be a planar tree (hinges about one axis, slides across "
                        "it: a lagrange.chain.Chain), got one that is not")


def check_schedule(task: AbstractTask, planar: bool = True) -> None:
    """Check a task's ``chain``, ``dt``, ``horizon`` and ``substeps`` (for a task's ``__check_init__``).

    Args:
        task: the task.
        planar: whether its chain must be planar (:func:`check_chain`).

    Raises:
        ValueError: naming the field that is out of range (``horizon``, ``substeps``: integers >= 1; ``dt`` > 0).
    """
    cls = type(task).__name__
    check_chain(task, planar)
    for field in ("horizon", "substeps"):
        v = getattr(task, field)
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{cls}.{field} must be an integer >= 1, got {v!r}")
    check_number(task, "dt", 0.0, open_low=True)
    try:
        check_solver(task.solver)
    except TypeError as err:
        raise TypeError(f"{cls}.{err}") from None


def check_number(task: AbstractTask, field: str, low: float, high: float = math.inf, *,
                 open_low: bool = False) -> None:
    """Check that a task's ``field`` is a real number (not a bool or a string) in ``[low, high]``.

    Args:
        task: the task.
        field: the field's name.
        low: the lower end.
        high: the upper end.
        open_low: exclude ``low`` itself.

    Raises:
        ValueError: naming ``<class>.<field>`` and the range.
    """
    v = getattr(task, field)
    ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
    if not ok or not (v > low if open_low else v >= low) or not v <= high:
        ends = ("(" if open_low else "[") + f"{low:g}, {high:g}" + ("]" if high < math.inf else ")")
        raise ValueError(f"{type(task).__name__}.{field} must be a number in {ends}, got {v!r}")


JOINT_NAMES = {Hinge: "revolute", Slide: "prismatic"}
"""A planar chain's words for its joints' kinds."""


def joint_kinds(tree: Tree) -> tuple[str, ...]:
    """Each joint's kind as a planar chain names it: ``"revolute"`` (a hinge), ``"prismatic"`` (a slide), else the
    joint's class name."""
    return tuple(JOINT_NAMES.get(type(j), type(j).__name__) for j in tree.joints)


def check_joints(task: AbstractTask, joints: tuple[str, ...]) -> None:
    """Check that a task's chain is planar with the joint kinds ``joints`` and a motor (for a task's
    ``__check_init__``).

    Args:
        task: the task.
        joints: the joint kinds its chain must have, in order (``("prismatic", "revolute")``: a slide, a hinge).

    Raises:
        ValueError: naming ``chain`` and the joints it must have, or that it has no actuated joint.
    """
    cls = type(task).__name__
    check_chain(task)
    if joint_kinds(task.chain) != joints:
        raise ValueError(f"{cls}.chain must have the joints {joints}, got {joint_kinds(task.chain)}")
    if task.chain.m < 1:
        raise ValueError(f"{cls}.chain must be actuated (some link with a gear), got chain.m=0")
