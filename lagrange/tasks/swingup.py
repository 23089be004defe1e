"""Swing-up tasks of the CE-APG paper on exact reduced-coordinate chains.

:class:`Acrobot`, :class:`Cartpole` (Table I's "Pendulum") and :class:`DoubleCartpole` are the paper's three tasks,
each documented by a table of its state, action, observation and reward; :class:`ChainSwingup` gives any fixed-base
revolute chain with a motor the acrobot's observation and reward. All four share :class:`AbstractSwingup`'s fields
and reset: episodes of 500 control steps without early termination, starting hanging down with uniform noise in
``[-0.01, 0.01]`` on every coordinate and velocity (the cart position included). Angles are wrapped to
``(-pi, pi]``, 0 upright for the first pole (``th1 = wrap(q1 - pi)``) and straight for later links
(``th2 = wrap(q2)``), as in the authors' environments.

Body sets. ``Acrobot.rods()`` (likewise ``Cartpole.rods()``, ``DoubleCartpole.rods()``) builds the task on this
library's bodies: the paper-facts, with thin-rod inertias ``m l^2 / 12`` and 1 m links where the paper states no
length (acrobot two links 1 m, 2.5 kg; cartpole cart 10.47 kg, pole 5.02 kg, 1 m; double cartpole cart 10.47 kg,
poles 5.02 kg, 1 m each). ``Acrobot.brax_v1()`` builds the same task (reward, observation, gear, dt and noise
unchanged) on the bodies the authors' Brax v1 configs describe: shorter hinge spacings, every inertia 1 kg m^2
(:data:`lagrange.systems.BRAX_V1`). Both take the task's fields as keywords (``Acrobot.rods(trig=True,
horizon=100)``); ``Acrobot(chain)`` puts the task on a chain of one's own. Control intervals: acrobot 0.01 s,
cartpole 0.04 s, double cartpole 0.01 s.

Integrator. Each control interval is one classic RK4 step (``lg.RK4()``, ``substeps=1``); the authors' Brax substep
counts (4, 8, 12) were needed by a stiff spring-joint engine, not by exact reduced coordinates. Measured final-state
error of a 500-step episode under an energetic open-loop pumping action, against ``Dopri8`` at
``rtol = atol = 1e-12`` in float64 (max over the episode in brackets), angles in rad:

=================  =================  =================  =================  ====================
solver, substeps   acrobot            cartpole           double cartpole    cost (force evals)
=================  =================  =================  =================  ====================
SemiImplicitEuler 4  5.4e-1 (7.3e-1)  1.9e-1 (1.9e-1)    2.3e-1 (1.4e+0)    4
SemiImplicitEuler 8  2.3e-1 (4.0e-1)  1.0e-1 (1.0e-1)    2.2e-1 (7.2e-1)    8
RK4 1              1.9e-5 (1.1e-4)    1.9e-4 (1.9e-4)    4.8e-5 (1.4e-4)    4
RK4 2              4.7e-7 (2.9e-6)    5.0e-6 (6.9e-6)    7.3e-7 (3.3e-6)    8
RK4 4              6.2e-9 (5.6e-8)    9.9e-8 (4.9e-7)    2.6e-8 (4.3e-8)    16
=================  =================  =================  =================  ====================

RK4 with one step per interval is 50-500 times below the +-0.01 rad reset noise (the scale below which two
episodes are indistinguishable to the task) and close to float32 round-off (float32 RK4 gives 1e-5..7e-5 at every
substep count), so more substeps would buy nothing; the Euler variants at the same cost are off by tenths of a
radian.
"""

from collections.abc import Callable
from typing import ClassVar, Self, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar, AbstractVar
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from lagrange import systems
from lagrange.model.tree import Tree
from lagrange.integrate.solvers import RK4
from lagrange.tasks.base import (TaskSolver, TaskState, check_chain, check_joints, check_number,
                                 check_schedule, joint_kinds)
from lagrange.tasks.poles import AbstractPoleTask

__all__ = ["AbstractSwingup", "AbstractPaperSwingup", "Acrobot", "Cartpole", "DoubleCartpole", "ChainSwingup",
           "PAPER_TASKS", "BODY_SETS"]

BODY_SETS = ("rods", "brax_v1")
"""The body sets of the paper tasks, by the name of their constructors: this library's rods (``Acrobot.rods()``), or
the CE-APG authors' Brax v1 bodies (``Acrobot.brax_v1()``, :data:`lagrange.systems.BRAX_V1`)."""


class AbstractSwingup(AbstractPoleTask):
    """A swing-up task of the CE-APG paper: the fields and the reset its tasks share (all but ``chain``
    keyword-only; the defaults are the paper's).

    Attributes:
        chain (Tree): the chain.
        dt (float): the control interval [s], > 0 (each final class has its default).
        horizon (int): control steps per episode, >= 1 (paper: 500).
        substeps (int): steps of ``solver`` per interval, >= 1 (1; see the module's table).
        solver (TaskSolver): the integrator (``RK4()``).
        noise (float): half-width >= 0 of the uniform reset noise on every ``q`` [rad, m] and ``qd`` [rad/s, m/s]
            (paper: 0.01).
        upright (float): the probability in [0, 1] of starting balanced upright instead of hanging (paper: 0); 1
            gives a balance-only task, a fraction is a training curriculum. The coin has its own key, so
            ``upright=0`` draws exactly the paper's starts.
        starts (Float[Array, "K 2*n"] | None): a start-state curriculum of ``K >= 1`` finite states ``(q, qd)``
            (e.g. states along a known swing-up, training from the end backwards): each reset draws a row uniformly,
            plus the same noise, instead of hanging; the ``upright`` coin still comes first. None: hanging.
        bodies (str | None): a label, ``"rods"`` or ``"brax_v1"`` for a task built by those constructors (see
            :data:`BODY_SETS`), None for one built on another chain. Only recorded, never switched on.
    """

    chain: Tree
    dt: AbstractVar[float]
    horizon: int = eqx.field(static=True, default=500, kw_only=True)
    substeps: int = eqx.field(static=True, default=1, kw_only=True)
    noise: float = eqx.field(static=True, default=0.01, kw_only=True)
    solver: TaskSolver = eqx.field(
        static=True, default=RK4(), kw_only=True)
    upright: float = eqx.field(static=True, default=0.0, kw_only=True)
    starts: Float[Array, "K 2*n"] | None = eqx.field(default=None, kw_only=True)
    bodies: str | None = eqx.field(static=True, default=None, kw_only=True)
    trig: AbstractVar[bool]

    def __check_init__(self):
        cls = type(self).__name__
        check_schedule(self)
        check_number(self, "noise", 0.0)
        check_number(self, "upright", 0.0, 1.0)
        if not isinstance(self.trig, bool):
            raise ValueError(f"{cls}.trig must be True or False, got {self.trig!r}")
        if self.bodies is not None and self.bodies not in BODY_SETS:
            raise ValueError(f"{cls}.bodies must be None or one of {list(BODY_SETS)}, got {self.bodies!r}")
        if self.starts is not None and not isinstance(self.starts, jax.core.Tracer):
            shape, want = np.shape(self.starts), 2 * self.chain.nv
            if len(shape) != 2 or shape[0] < 1 or shape[1] != want:
                raise ValueError(f"{cls}.starts must be an array of shape (K >= 1, 2 n = {want}) of states (q, qd), "
                                 f"got shape {shape}")
            if not np.all(np.isfinite(np.asarray(self.starts))):
                raise ValueError(f"{cls}.starts must be finite")

    def reset(self, key: PRNGKeyArray) -> TaskState:
        """Hanging down (or a state drawn uniformly from ``starts``), with uniform noise in ``[-noise, noise]`` on
        every ``q`` and ``qd``; balanced upright instead with probability ``upright`` (1: always, a balance-only
        task).

        Args:
            key: the PRNG key of the start.
        """
        n = self.chain.nv
        dtype = jnp.result_type(self.chain.mass)
        kq, kv = jax.random.split(key)
        q = jax.random.uniform(kq, (n,), dtype, -self.noise, self.noise)
        qd = jax.random.uniform(kv, (n,), dtype, -self.noise, self.noise)
        hanging = jnp.zeros(n, dtype)
        start_q, start_qd = hanging, hanging
        if self.starts is not None:  # its own key too, so the noise is the same as without starts
            x = self.starts[jax.random.randint(jax.random.fold_in(key, 0x5A), (), 0, self.starts.shape[0])]
            start_q, start_qd = x[:n].astype(dtype), x[n:].astype(dtype)
        upright = hanging.at[self.first_pole].set(jnp.pi)
        p = float(self.upright)
        if p >= 1:
            start_q, start_qd = upright, hanging
        elif p > 0:  # the coin has its own key, so p = 0 draws exactly the paper's starts
            up = jax.random.bernoulli(jax.random.fold_in(key, 0x0B), p)
            start_q, start_qd = jnp.where(up, upright, start_q), jnp.where(up, hanging, start_qd)
        return TaskState(q + start_q, qd + start_qd)

    @property
    def observation_size(self) -> int:
        return 3 * self.n_links + (2 if self.cart else 0) if self.trig else 2 * self.chain.nv

    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """``(x, th, dx, dth)``, or ``(x, sin th, cos th, dx, dth)`` with ``trig`` (``x, dx`` only with a cart; each
        final class's table gives its layout).

        Args:
            state: the state.
        """
        th, dth = self.angles(state), self.angular_velocities(state)
        x, dx = (state.q[:1], state.qd[:1]) if self.cart else (state.q[:0], state.qd[:0])
        if self.trig:
            return jnp.concatenate([x, jnp.sin(th), jnp.cos(th), dx, dth])
        return jnp.concatenate([x, th, dx, dth])


class AbstractPaperSwingup(AbstractSwingup):
    """One of the CE-APG paper's three tasks: built on this library's rods (:meth:`rods`) or on the authors' Brax v1
    bodies (:meth:`brax_v1`) of its system in :mod:`lagrange.systems`.

    Attributes:
        system (ClassVar): the function of :mod:`lagrange.systems` that builds the task's chain; its keywords for
            the Brax v1 bodies are ``lagrange.systems.BRAX_V1[name]``.
    """

    system: AbstractClassVar[Callable[..., Tree]]

    @classmethod
    def rods(cls, **options) -> Self:
        """The paper's task on this library's rods (``cls.system()``, e.g. :func:`lagrange.systems.acrobot`);
        ``options`` are the task's fields (``trig`` where it has one, ``horizon``, ``noise``, ``upright``,
        ``starts``, ``solver``, ``substeps``).

        Args:
            **options: the task's fields, keywords (``horizon=100``...).
        """
        return cls(cls.system(), bodies="rods", **options)

    @classmethod
    def brax_v1(cls, **options) -> Self:
        """The paper's task on the authors' Brax v1 bodies (``lagrange.systems.BRAX_V1[cls.name]``); ``options`` as
        for :meth:`rods`.

        Args:
            **options: the task's fields, keywords (``horizon=100``...).
        """
        return cls(cls.system(**systems.BRAX_V1[cls.name]), bodies="brax_v1", **options)


def _upright_reward(task: AbstractPoleTask, next_state: TaskState) -> Float[Array, ""]:
    """``10 - sum th^2 - 0.01 sum dth^2`` of ``next_state``."""
    th, dth = task.angles(next_state), task.angular_velocities(next_state)
    return 10.0 - jnp.sum(th**2) - 0.01 * jnp.sum(dth**2)


@final
class Acrobot(AbstractPaperSwingup):
    """Acrobot swing-up: two links, a passive shoulder and a motor at the elbow.

    =====================  ========================================================================================
    state ``q`` / ``qd``   (q1, q2) / (qd1, qd2): shoulder and elbow angles, relative, 0 hanging straight [rad]
    action (gear)          elbow torque ``25 a`` N m, ``a`` clipped to [-1, 1]
    observation (4,)       (th1, th2, dth1, dth2); ``trig=True``: (sin th1, sin th2, cos th1, cos th2, dth1, dth2)
    reward per step        ``10 - (th1^2 + th2^2) - 0.01 (dth1^2 + dth2^2)``; max 5000
    episode                500 control steps of dt = 0.01 s, no early termination
    reset                  hanging down, U(-0.01, 0.01) on every coordinate and velocity
    =====================  ========================================================================================

    Build it with :meth:`~AbstractPaperSwingup.rods` or :meth:`~AbstractPaperSwingup.brax_v1`, or
    ``Acrobot(chain)`` on a two-link chain of one's own (:func:`lagrange.systems.acrobot`); the other fields are
    :class:`AbstractSwingup`'s.

    Attributes:
        dt (float): the control interval [s] (paper: 0.01).
        trig (bool): observe ``(sin th, cos th, dth)`` instead of the wrapped angles, which jump by 2 pi at every
            swing through hanging (not the paper's: False).
    """

    dt: float = eqx.field(static=True, default=0.01, kw_only=True)
    trig: bool = eqx.field(static=True, default=False, kw_only=True)

    first_pole: ClassVar[int] = 0
    name: ClassVar[str] = "acrobot"
    system: ClassVar[Callable[..., Tree]] = staticmethod(systems.acrobot)

    def __check_init__(self):
        check_joints(self, ("revolute", "revolute"))

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """``10 - (th1^2 + th2^2) - 0.01 (dth1^2 + dth2^2)`` of ``next_state``."""
        del state, action
        return _upright_reward(self, next_state)


@final
class Cartpole(AbstractPaperSwingup):
    """Cartpole swing-up (the paper's Table I "Pendulum"): a motorised cart on a rail carrying a passive pole.

    =====================  ========================================================================================
    state ``q`` / ``qd``   (x, q) / (dx, dq): cart position [m], pole angle relative to hanging down [rad]
    action (gear)          cart force ``100 a`` N, ``a`` clipped to [-1, 1]
    observation (4,)       (x, th, dx, dth); ``trig=True``: (x, sin th, cos th, dx, dth)
    reward per step        ``-th^2``; max 0
    episode                500 control steps of dt = 0.04 s, no early termination
    reset                  hanging down, U(-0.01, 0.01) on every coordinate and velocity (the cart's included)
    =====================  ========================================================================================

    Build it with :meth:`~AbstractPaperSwingup.rods` or :meth:`~AbstractPaperSwingup.brax_v1`, or
    ``Cartpole(chain)`` on a chain of :func:`lagrange.systems.cartpole`; the other fields are
    :class:`AbstractSwingup`'s.

    Attributes:
        dt (float): the control interval [s] (paper: 0.04).
        trig (bool): observe ``(x, sin th, cos th, dx, dth)`` instead of the wrapped angle (paper: False).
    """

    dt: float = eqx.field(static=True, default=0.04, kw_only=True)
    trig: bool = eqx.field(static=True, default=False, kw_only=True)

    first_pole: ClassVar[int] = 1
    name: ClassVar[str] = "cartpole"
    system: ClassVar[Callable[..., Tree]] = staticmethod(systems.cartpole)

    def __check_init__(self):
        check_joints(self, ("prismatic", "revolute"))

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """``-th^2`` of ``next_state``."""
        del state, action
        th = self.angles(next_state)
        return -jnp.sum(th**2)


@final
class DoubleCartpole(AbstractPaperSwingup):
    """Double-cartpole swing-up: a motorised cart carrying two passive poles in series.

    =====================  ========================================================================================
    state ``q`` / ``qd``   (x, q1, q2) / (dx, dq1, dq2): cart position [m], relative pole angles, 0 hanging [rad]
    action (gear)          cart force ``1000 a`` N, ``a`` clipped to [-1, 1]
    observation (8,)       (x, sin th1, sin th2, cos th1, cos th2, dx, dth1, dth2)
    reward per step        ``10 - (th1^2 + th2^2 + x^2) - 0.01 (dth1^2 + dth2^2)``; max 5000
    episode                500 control steps of dt = 0.01 s, no early termination
    reset                  hanging down, U(-0.01, 0.01) on every coordinate and velocity (the cart's included)
    =====================  ========================================================================================

    Build it with :meth:`~AbstractPaperSwingup.rods` or :meth:`~AbstractPaperSwingup.brax_v1`, or
    ``DoubleCartpole(chain)`` on a chain of :func:`lagrange.systems.double_cartpole`; the other fields are
    :class:`AbstractSwingup`'s.

    Attributes:
        dt (float): the control interval [s] (paper: 0.01).
        trig (ClassVar[bool]): True: the observation is always the trigonometric layout.
    """

    dt: float = eqx.field(static=True, default=0.01, kw_only=True)

    trig: ClassVar[bool] = True
    first_pole: ClassVar[int] = 1
    name: ClassVar[str] = "double_cartpole"
    system: ClassVar[Callable[..., Tree]] = staticmethod(systems.double_cartpole)

    def __check_init__(self):
        check_joints(self, ("prismatic", "revolute", "revolute"))

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """``10 - (th1^2 + th2^2 + x^2) - 0.01 (dth1^2 + dth2^2)`` of ``next_state``."""
        del state, action
        return _upright_reward(self, next_state) - next_state.q[0] ** 2


@final
class ChainSwingup(AbstractSwingup):
    """Swing-up of any fixed-base chain of revolute links with at least one motor, with the acrobot's observation
    and reward.

    =====================  ========================================================================================
    state ``q`` / ``qd``   (q1, ..., qn) / (qd1, ..., qdn): relative joint angles, 0 hanging straight [rad]
    action (gear)          torques ``gear_k a_k`` N m on the actuated joints, ``a`` clipped to [-1, 1]
    observation (2n,)      (th1, ..., thn, dth1, ..., dthn); ``trig=True``: (sin th, cos th, dth), (3n,)
    reward per step        ``10 - sum th_i^2 - 0.01 sum dth_i^2``; max 10 per step
    episode                ``horizon`` control steps of ``dt`` (defaults 500 and 0.01 s), no early termination
    reset                  hanging down, U(-noise, noise) on every coordinate and velocity
    =====================  ========================================================================================

    ``ChainSwingup(chain, dt=0.05, horizon=100, upright=1.0)`` is a balance-only task on ``chain``. Raises
    ``ValueError`` for a chain with a prismatic joint or without a motor. The other fields are
    :class:`AbstractSwingup`'s.

    Attributes:
        dt (float): the control interval [s] (0.01).
        trig (bool): observe ``(sin th, cos th, dth)`` instead of the wrapped angles.
    """

    dt: float = eqx.field(static=True, default=0.01, kw_only=True)
    trig: bool = eqx.field(static=True, default=False, kw_only=True)

    first_pole: ClassVar[int] = 0
    name: ClassVar[str] = "chain"

    def __check_init__(self):
        check_chain(self)
        if any(j != "revolute" for j in joint_kinds(self.chain)):
            raise ValueError(f"ChainSwingup needs revolute joints only, got joints={joint_kinds(self.chain)}")
        if self.chain.m < 1:
            raise ValueError("ChainSwingup needs an actuated chain (some link with a gear), got chain.m=0")

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """``10 - sum th_i^2 - 0.01 sum dth_i^2`` of ``next_state``."""
        del state, action
        return _upright_reward(self, next_state)


PAPER_TASKS: dict[str, type[AbstractSwingup]] = {"acrobot": Acrobot, "cartpole": Cartpole,
                                                 "double_cartpole": DoubleCartpole}
"""The CE-APG paper's tasks by name (for command lines): ``PAPER_TASKS[name].rods()`` or ``.brax_v1()``."""
