"""Swing-up tasks of the CE-APG paper on exact reduced-coordinate chains.

A task is a pure, immutable :class:`eqx.Module`: ``reset(key) -> state``, ``step(state, action)
-> state``, ``observe(state) -> obs`` and ``reward(state, action, next_state) -> r`` (the reward
of a transition is a function of the state it lands in, as in Brax). Nothing is stored between
calls, so every method can be ``jit``-ed, ``vmap``-ed and differentiated.

Conventions. The chains of :mod:`lagrange.systems` hang down at ``q = 0`` and use *relative*
joint angles. The tasks report angles wrapped to ``(-pi, pi]`` with 0 meaning upright for the
first pole (``th1 = wrap(q1 - pi)``) and straight for later links (``th2 = wrap(q2)``), as in the
authors' environments. Actions ``a`` are clipped to ``[-1, 1]`` and multiplied by the chain's gear.
Episodes last 500 control steps, without early termination. Reset: hanging down, with uniform noise
in ``[-0.01, 0.01]`` on every coordinate and velocity (the cart position included).

===============  ===============================  =======================  =============================================  ==========================================================
task             state ``q`` / ``qd``             action (gear)            observation                                    reward per step (``th`` wrapped, 0 upright)
===============  ===============================  =======================  =============================================  ==========================================================
acrobot          (q1, q2) / (qd1, qd2)            elbow torque 25 a N m    (th1, th2, dth1, dth2)                         10 - (th1^2 + th2^2) - 0.01 (dth1^2 + dth2^2); max 5000
cartpole         (x, q) / (dx, dq)                cart force 100 a N       (x, th, dx, dth)                               -th^2; max 0
double_cartpole  (x, q1, q2) / (dx, dq1, dq2)     cart force 1000 a N      (x, sin th1, sin th2, cos th1, cos th2,        10 - (th1^2 + th2^2 + x^2) - 0.01 (dth1^2 + dth2^2);
                                                                           dx, dth1, dth2)                                max 5000
===============  ===============================  =======================  =============================================  ==========================================================

``Task(..., trig=True)`` observes ``(sin th, cos th, dth)`` (plus ``x, dx`` with a cart) instead of the
wrapped angles; it is the double cartpole's layout and an option elsewhere (the acrobot example uses
it: the wrapped first angle jumps by 2 pi at every swing through hanging). ``upright=p`` starts
balanced with probability ``p`` (``upright=1``: balance-only variants, used in tests; a fraction is a
training curriculum, see ``CEAPGConfig.upright_starts``; the paper's tasks use 0). ``starts=X`` (K, 2n) replaces the
hanging start by one of the states ``X[k] = (q, qd)``, drawn uniformly, plus the same noise: a start-state
curriculum (e.g. states along a known swing-up, training from the end backwards); the ``upright`` coin still
comes first.
``chain_swingup(chain)`` makes the acrobot's task for any fixed-base revolute chain with at least one motor.

Physical parameters (paper-facts; unstated ones chosen and documented in :mod:`lagrange.systems`):
acrobot two links 1 m, 2.5 kg; cartpole cart 10.47 kg, pole 5.02 kg, 1 m; double cartpole cart
10.47 kg, poles 5.02 kg, 1 m each; thin-rod inertias ``m l^2 / 12``. Control intervals: 0.01 s,
0.04 s, 0.01 s. ``make_task(name, bodies="brax_v1")`` puts the same task on the bodies the authors' Brax v1
configs describe (shorter hinge spacings, every inertia 1 kg m^2; ``lagrange.systems.BRAX_V1``).

Integrator. Each control interval is one classic RK4 step (``lg.RK4()``, ``substeps=1``); the
authors' Brax substep counts (4, 8, 12) were needed by a stiff spring-joint engine, not by exact
reduced coordinates. Measured final-state error of a 500-step episode under an energetic open-loop
pumping action, against ``Dopri8`` at ``rtol = atol = 1e-12`` in float64 (script in the helper's
report; max over the episode in brackets), angles in rad:

=================  =================  =================  =================  ====================
solver, substeps   acrobot            cartpole           double cartpole    cost (force evals)
=================  =================  =================  =================  ====================
SemiImplicitEuler 4  5.4e-1 (7.3e-1)  1.9e-1 (1.9e-1)    2.3e-1 (1.4e+0)    4
SemiImplicitEuler 8  2.3e-1 (4.0e-1)  1.0e-1 (1.0e-1)    2.2e-1 (7.2e-1)    8
RK4 1              1.9e-5 (1.1e-4)    1.9e-4 (1.9e-4)    4.8e-5 (1.4e-4)    4
RK4 2              4.7e-7 (2.9e-6)    5.0e-6 (6.9e-6)    7.3e-7 (3.3e-6)    8
RK4 4              6.2e-9 (5.6e-8)    9.9e-8 (4.9e-7)    2.6e-8 (4.3e-8)    16
=================  =================  =================  =================  ====================

RK4 with one step per interval is 50-500 times below the +-0.01 rad reset noise (the scale below
which two episodes are indistinguishable to the task) and close to float32 round-off (float32 RK4
gives 1e-5..7e-5 at every substep count), so more substeps would buy nothing; the Euler variants
at the same cost are off by tenths of a radian.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lagrange import systems
from lagrange.chain import Chain
from lagrange.integrate import step as _step
from lagrange.solvers import RK4

__all__ = ["TaskState", "Task", "control_step", "acrobot", "cartpole", "double_cartpole", "make_task", "TASKS",
           "BODIES", "balanced", "leaves_upright", "upright_error", "wrap", "chain_swingup"]


def wrap(angle):
    """Wrap angles to ``(-pi, pi]``."""
    return jnp.pi - jnp.mod(jnp.pi - angle, 2 * jnp.pi)


class TaskState(NamedTuple):
    """Generalized coordinates ``q`` (n,) and velocities ``qd`` (n,) of the chain."""

    q: jax.Array
    qd: jax.Array


def control_step(task, state: TaskState, action) -> TaskState:
    """One control interval ``task.dt`` (``task.substeps`` solver steps of ``task.solver``) under
    ``clip(action, -1, 1)`` times the chain's gear; the ``step`` of every task here."""
    a = jnp.clip(action, -1.0, 1.0)
    q, qd = _step(task.chain, state.q, state.qd, a, task.dt, task.solver, task.substeps)
    return TaskState(q, qd)


class Task(eqx.Module):
    """A planar-chain swing-up task (final class; build one with :func:`make_task`).

    ``kind`` selects the observation and reward ("acrobot", "cartpole", "double_cartpole", or
    "chain" for a fixed-base chain of revolute links with the acrobot's reward, used by
    :func:`chain_swingup`). ``cart`` says whether ``q[0]`` is a prismatic cart coordinate.
    ``trig=True`` (not the paper's, except for the double cartpole where it is the default layout)
    observes ``(x, sin th, cos th, dx, dth)`` instead of the wrapped angles, which jump by 2 pi as a
    pole swings through hanging. ``bodies`` records which bodies :func:`make_task` built a paper task on ("rods" or
    "brax_v1"); None for a task built any other way (a custom chain, or :func:`acrobot` etc. with chain keywords).
    """

    chain: Chain
    kind: str = eqx.field(static=True)
    dt: float = eqx.field(static=True)
    horizon: int = eqx.field(static=True, default=500)
    substeps: int = eqx.field(static=True, default=1)
    noise: float = eqx.field(static=True, default=0.01)
    solver: object = eqx.field(static=True, default=RK4())
    upright: float = eqx.field(static=True, default=0.0)
    trig: bool = eqx.field(static=True, default=False)
    starts: jax.Array | None = None
    bodies: str | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if not 0 <= float(self.upright) <= 1:
            raise ValueError(f"Task.upright must be a probability in [0, 1], got {self.upright!r}")
        if self.bodies is not None and self.bodies not in BODIES:
            raise ValueError(f"Task.bodies must be None or one of {list(BODIES)}, got {self.bodies!r}")
        if self.starts is not None and not isinstance(self.starts, jax.core.Tracer):
            shape, want = np.shape(self.starts), 2 * self.chain.n
            if len(shape) != 2 or shape[0] < 1 or shape[1] != want:
                raise ValueError(f"Task.starts must be an array of shape (K >= 1, 2 n = {want}) of states (q, qd), "
                                 f"got shape {shape}")
            if not np.all(np.isfinite(np.asarray(self.starts))):
                raise ValueError("Task.starts must be finite")

    @property
    def cart(self) -> bool:
        return self.kind in ("cartpole", "double_cartpole")

    @property
    def first_pole(self) -> int:
        """Index in ``q`` of the first pole's joint: 1 after a cart, else 0."""
        return 1 if self.cart else 0

    @property
    def n_links(self) -> int:
        """Number of poles (revolute links)."""
        return self.chain.n - self.first_pole

    @property
    def action_size(self) -> int:
        return self.chain.m

    @property
    def observation_size(self) -> int:
        n = self.n_links
        if self.kind == "double_cartpole" or self.trig:
            return 3 * n + (2 if self.cart else 0)
        return self.chain.n * 2

    # -- state ------------------------------------------------------------------------------
    def reset(self, key) -> TaskState:
        """Hanging down (or a state drawn uniformly from ``starts``), with uniform noise in ``[-noise, noise]`` on
        every ``q`` and ``qd``; balanced upright instead with probability ``upright`` (1: always, a balance-only
        task)."""
        n = self.chain.n
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

    def step(self, state: TaskState, action) -> TaskState:
        """One control interval ``dt`` under ``clip(action, -1, 1)`` times the chain's gear."""
        return control_step(self, state, action)

    # -- readings -----------------------------------------------------------------------------
    def angles(self, state: TaskState):
        """Pole angles (n_links,), wrapped, 0 = first pole upright / later links straight."""
        rel = state.q[self.first_pole:]
        offset = jnp.zeros_like(rel).at[0].set(jnp.pi)
        return wrap(rel - offset)

    def link_angles(self, state: TaskState):
        """Absolute pole orientations (n_links,), wrapped, 0 = pointing straight up."""
        return _link_angles(self, state.q)

    def angular_velocities(self, state: TaskState):
        return state.qd[self.first_pole:]

    def observe(self, state: TaskState):
        """The authors' observation vector (see the module table)."""
        th, dth = self.angles(state), self.angular_velocities(state)
        if self.kind == "double_cartpole" or self.trig:
            x, dx = (state.q[:1], state.qd[:1]) if self.cart else (state.q[:0], state.qd[:0])
            return jnp.concatenate([x, jnp.sin(th), jnp.cos(th), dx, dth])
        if self.cart:
            return jnp.concatenate([state.q[:1], th, state.qd[:1], dth])
        return jnp.concatenate([th, dth])

    def reward(self, state: TaskState, action, next_state: TaskState):
        """Reward of the transition ``state --action--> next_state`` (a function of ``next_state``)."""
        del state, action
        th, dth = self.angles(next_state), self.angular_velocities(next_state)
        if self.kind == "cartpole":
            return -jnp.sum(th**2)
        r = 10.0 - jnp.sum(th**2) - 0.01 * jnp.sum(dth**2)
        if self.kind == "double_cartpole":
            r = r - next_state.q[0] ** 2
        return r


def acrobot(**chain_kwargs) -> Task:
    """Acrobot swing-up: elbow torque 25 a, dt 0.01 s, 500 steps (max return about 5000)."""
    return Task(systems.acrobot(**chain_kwargs), "acrobot", dt=0.01)


def cartpole(**chain_kwargs) -> Task:
    """Cartpole swing-up (Table I's "Pendulum"): cart force 100 a, dt 0.04 s, reward -th^2."""
    return Task(systems.cartpole(**chain_kwargs), "cartpole", dt=0.04)


def double_cartpole(**chain_kwargs) -> Task:
    """Double-cartpole swing-up: cart force 1000 a, dt 0.01 s (max return about 5000)."""
    return Task(systems.double_cartpole(**chain_kwargs), "double_cartpole", dt=0.01)


def chain_swingup(chain: Chain, *, dt: float = 0.01, horizon: int = 500, substeps: int = 1, noise: float = 0.01,
                  upright: float = 0.0) -> Task:
    """Swing-up of any fixed-base chain of revolute links, with the acrobot's observation and reward
    (``upright=1``: start balanced, a balance-only task; ``0 < upright < 1``: that fraction of starts)."""
    if any(j != "revolute" for j in chain.joints):
        raise ValueError(f"chain_swingup needs revolute joints only, got joints={chain.joints}")
    if chain.m < 1:
        raise ValueError("chain_swingup needs an actuated chain (some link with a gear), got chain.m=0")
    if not noise >= 0:
        raise ValueError(f"chain_swingup noise must be >= 0, got {noise!r}")
    return Task(chain, "chain", dt=dt, horizon=horizon, substeps=substeps, noise=noise, upright=upright)


TASKS = {"acrobot": acrobot, "cartpole": cartpole, "double_cartpole": double_cartpole}
"""The CE-APG paper's tasks by name: the constructors :func:`make_task` calls."""


BODIES = ("rods", "brax_v1")
"""The body sets of the paper tasks: this library's rods, or the CE-APG authors' Brax v1 bodies
(:data:`lagrange.systems.BRAX_V1`)."""


def make_task(name: str, bodies: str = "rods") -> Task:
    """The paper task called ``name`` (one of ``TASKS``) on ``bodies``: "rods", this library's (the lengths of
    paper-facts, thin-rod inertias), or "brax_v1", the authors' Brax v1 bodies (``lagrange.systems.BRAX_V1``)."""
    if name not in TASKS:
        raise ValueError(f"task must be one of {sorted(TASKS)}, got {name!r}")
    if bodies not in BODIES:
        raise ValueError(f"bodies must be one of {list(BODIES)}, got {bodies!r}")
    task = TASKS[name]() if bodies == "rods" else TASKS[name](**systems.BRAX_V1[name])
    return dataclasses.replace(task, bodies=bodies)


def balanced(task: Task, q, *, fraction: float = 0.2, tolerance: float = 0.2):
    """Whether every pole stays within ``tolerance`` rad of upright during the final ``fraction`` of an episode.

    ``q`` is a trajectory of coordinates (T, n) (leading batch dims allowed); "upright" is measured
    on each link's absolute orientation. Returns a boolean array of the batch shape.
    """
    q = jnp.asarray(q)
    T = q.shape[-2]
    start = T - max(1, int(np.ceil(fraction * T)))
    return jnp.all(upright_error(task, q[..., start:, :]) <= tolerance, axis=-1)


def leaves_upright(task: Task, q, *, tolerance: float, from_step: int = 0) -> np.ndarray:
    """How long a hold lasts: per episode, the first step ``t >= from_step`` at which some pole is more than
    ``tolerance`` rad from upright (:func:`upright_error`, as :func:`balanced` measures it), -1 where none is.

    ``q`` is a trajectory of coordinates (T, n) (leading batch dims allowed), step ``t`` at ``q[..., t, :]``; a
    non-finite step counts as having left. Returns a NumPy integer array of the batch shape (0-d for one episode).
    """
    q = jnp.asarray(q)
    if q.ndim < 2 or q.shape[-1] != task.chain.n:
        raise ValueError(f"leaves_upright: q must have shape (..., T, n = {task.chain.n}), got {q.shape}")
    if not tolerance > 0:
        raise ValueError(f"leaves_upright: tolerance must be > 0 (rad), got {tolerance!r}")
    if not (isinstance(from_step, (int, np.integer)) and 0 <= from_step < q.shape[-2]):
        raise ValueError(f"leaves_upright: from_step must be an integer in [0, T = {q.shape[-2]}), got {from_step!r}")
    left = ~(np.asarray(upright_error(task, q))[..., from_step:] <= tolerance)
    return np.where(left.any(axis=-1), from_step + left.argmax(axis=-1), -1)


def upright_error(task: Task, q):
    """The largest angle (rad) by which any pole is away from upright, per step: ``q`` (..., n) -> (...).

    Measured on each link's absolute orientation (the sum of the joint angles from the base), the cart excluded."""
    return jnp.max(jnp.abs(_link_angles(task, jnp.asarray(q))), axis=-1)


def _link_angles(task: Task, q):
    rel = q[..., task.first_pole:]
    return wrap(jnp.cumsum(rel, axis=-1) - jnp.pi)
