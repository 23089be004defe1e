"""Pole tasks: a chain carrying poles to balance (the swing-ups, the SHAC authors' cartpole), its angle readings, and
judging an episode: how far the poles are from upright, whether they end balanced, and how long a hold lasts.

Conventions: the chains of :mod:`lagrange.systems` hang down at ``q = 0`` and use *relative* joint angles; the tasks
report angles wrapped to ``(-pi, pi]`` with 0 meaning upright for the first pole (``th1 = wrap(q1 - pi)``) and
straight for later links (``th2 = wrap(q2)``); a cart, where there is one, is ``q[0]``; the poles follow it
(``first_pole``). The judges measure every pole by its absolute orientation (the sum of the joint angles from the
base, the cart excluded; :meth:`AbstractPoleTask.link_angles`), so an elbow bent back against a leaning shoulder
keeps the second link upright.
"""

import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from lagrange.tasks.base import AbstractTask, TaskState, check_state, wrap

__all__ = ["AbstractPoleTask", "pole_orientations", "balanced", "leaves_upright", "upright_error"]


class AbstractPoleTask(AbstractTask):
    """A task whose chain carries poles to balance (a cart, if any, is ``q[0]``); its angle readings, and success
    judged by :func:`lagrange.tasks.balanced`.

    Attributes:
        first_pole (ClassVar[int]): the index in ``q`` of the first pole's joint: 1 after a cart, else 0.
    """

    first_pole: AbstractClassVar[int]

    @property
    def cart(self) -> bool:
        """Whether ``q[0]`` is a prismatic cart coordinate (``first_pole == 1``)."""
        return self.first_pole == 1

    @property
    def n_links(self) -> int:
        """Number of poles (revolute links)."""
        return self.chain.nv - self.first_pole

    def angles(self, state: TaskState) -> Float[Array, " n_links"]:
        """Pole angles [rad], wrapped, 0 = first pole upright / later links straight, shape ``(n_links,)``.

        Args:
            state: one state (``jax.vmap`` over a batch).
        """
        check_state(self, state)
        rel = state.q[self.first_pole:]
        offset = jnp.zeros_like(rel).at[0].set(jnp.pi)
        return wrap(rel - offset)

    def link_angles(self, state: TaskState) -> Float[Array, " n_links"]:
        """Absolute pole orientations [rad], wrapped, 0 = pointing straight up, shape ``(n_links,)``.

        Args:
            state: one state (``jax.vmap`` over a batch).
        """
        check_state(self, state)
        return pole_orientations(self, state.q)

    def angular_velocities(self, state: TaskState) -> Float[Array, " n_links"]:
        """Joint velocities of the poles [rad/s], relative as the angles are, shape ``(n_links,)``.

        Args:
            state: one state (``jax.vmap`` over a batch).
        """
        check_state(self, state)
        return state.qd[self.first_pole:]

    def succeeded(self, q: Float[ArrayLike, "*batch T n"]) -> Bool[Array, " *batch"]:
        """Whether the poles end balanced (:func:`lagrange.tasks.balanced` with its defaults).

        Args:
            q: a trajectory of coordinates, shape ``(*batch, T, n)``.
        """
        return balanced(self, q)


def pole_orientations(task: AbstractPoleTask, q: Float[ArrayLike, "*batch n"]) -> Float[Array, "*batch n_links"]:
    """Absolute orientations of the poles [rad], wrapped to ``(-pi, pi]``, 0 = pointing straight up.

    Args:
        task: the task (its ``first_pole`` says where the poles start in ``q``).
        q: coordinates, shape ``(*batch, n)`` (a state's, or a trajectory's).

    Returns:
        The sum of the joint angles from the base to each pole minus pi, wrapped, shape ``(*batch, n_links)``.
    """
    rel = q[..., task.first_pole:]
    return wrap(jnp.cumsum(rel, axis=-1) - jnp.pi)


def balanced(task: AbstractPoleTask, q: Float[ArrayLike, "*batch T n"], *, fraction: float = 0.2,
             tolerance: float = 0.2) -> Bool[Array, " *batch"]:
    """Whether every pole stays within ``tolerance`` rad of upright during the final ``fraction`` of an episode
    ("upright" measured on each link's absolute orientation).

    Args:
        task: the task (where its poles start in ``q``).
        q: a trajectory of coordinates, shape ``(*batch, T, n)``.
        fraction: the share of the episode's end that must hold, in (0, 1].
        tolerance: the largest angle from upright allowed [rad].

    Returns:
        A boolean array of the batch shape.
    """
    q = jnp.asarray(q)
    if q.ndim < 2:
        raise ValueError(f"balanced: q must have shape (..., T, n = {task.chain.nv}), a trajectory, got {q.shape}")
    for name, value, ok in (("fraction", fraction, lambda v: 0 < v <= 1), ("tolerance", tolerance, lambda v: v > 0)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not ok(value):
            raise ValueError(f"balanced: {name} must be a number in {'(0, 1]' if name == 'fraction' else '(0, inf)'}"
                             f", got {value!r}")
    T = q.shape[-2]
    start = T - max(1, int(np.ceil(fraction * T)))
    return jnp.all(upright_error(task, q[..., start:, :]) <= tolerance, axis=-1)


def leaves_upright(task: AbstractPoleTask, q: Float[ArrayLike, "*batch T n"], *, tolerance: float,
                   from_step: int = 0) -> Int[np.ndarray, " *batch"]:
    """How long a hold lasts: per episode, the first step ``t >= from_step`` at which some pole is more than
    ``tolerance`` rad from upright (:func:`upright_error`, as :func:`balanced` measures it), -1 where none is; a
    non-finite step counts as having left.

    Args:
        task: the task.
        q: a trajectory of coordinates, shape ``(*batch, T, n)``, step ``t`` at ``q[..., t, :]``.
        tolerance: the largest angle from upright allowed [rad], > 0.
        from_step: the first step looked at, in ``[0, T)``.

    Returns:
        A NumPy integer array of the batch shape (0-d for one episode).

    Raises:
        ValueError: for a ``q``, ``tolerance`` or ``from_step`` out of range.
    """
    q = jnp.asarray(q)
    if q.ndim < 2 or q.shape[-1] != task.chain.nv:
        raise ValueError(f"leaves_upright: q must have shape (..., T, n = {task.chain.nv}), got {q.shape}")
    if not tolerance > 0:
        raise ValueError(f"leaves_upright: tolerance must be > 0 (rad), got {tolerance!r}")
    if not (isinstance(from_step, (int, np.integer)) and 0 <= from_step < q.shape[-2]):
        raise ValueError(f"leaves_upright: from_step must be an integer in [0, T = {q.shape[-2]}), got {from_step!r}")
    left = ~(np.asarray(upright_error(task, q))[..., from_step:] <= tolerance)
    return np.where(left.any(axis=-1), from_step + left.argmax(axis=-1), -1)


def upright_error(task: AbstractPoleTask, q: Float[ArrayLike, "*batch n"]) -> Float[Array, " *batch"]:
    """The largest angle [rad] by which any pole is away from upright, measured on each link's absolute orientation
    (the sum of the joint angles from the base), the cart excluded.

    Args:
        task: the task.
        q: coordinates, shape ``(*batch, n)``.

    Returns:
        Shape ``(*batch,)``.
    """
    q = jnp.asarray(q)
    if q.ndim < 1 or q.shape[-1] != task.chain.nv:
        raise ValueError(f"upright_error: q must have shape (..., n = {task.chain.nv}), got {q.shape}")
    return jnp.max(jnp.abs(pole_orientations(task, q)), axis=-1)
