"""The SHAC authors' cartpole swing-up (NVlabs/DiffRL ``CartPoleSwingUpEnv``) on an exact chain.

:class:`DiffRLCartpole` is a task like the CE-APG paper's (usable by every optimiser and by
:func:`lagrange.tasks.balanced`), with the DiffRL environment's physics, observation, reward and reset instead.

Physical parameters. DiffRL's URDF loader takes masses from the collision shapes at density 1000 kg/m^3 and ignores
the URDF's ``<inertial>``: the cart box 0.5 x 0.5 x 0.2 m gives **50 kg**, the pole box 0.05 x 0.05 x 1.0 m gives
**2.5 kg**, centre of mass at 0.5 m, inertia about the centre of mass ``m (l^2 + w^2) / 12 = 0.20885 kg m^2``
(:data:`POLE_INERTIA`; a box, not a thin rod). No armature, no joint damping, gravity 9.81. The authors' cart rail
has a soft limit at +-4 m (spring 100 N/m, damper 1 N s/m); this chain has no joint limits (the reward's
``0.05 x^2 + 0.1 dx^2`` keeps a trained cart near 0).

Integrator. The authors ran dflex's semi-implicit Euler with 4 substeps per 1/60 s interval. Here the default is one
classic RK4 step per interval (the same 4 force evaluations); ``solver=lg.SemiImplicitEuler(), substeps=4``
reproduces the authors' integrator. Largest error of any coordinate or velocity over a 240-step episode under the
open-loop pumping action ``a = sin(3.84 t)`` (the pole's natural frequency; the pole goes over the top, |q| reaches
9.2 rad), against ``Dopri8`` at ``rtol = atol = 1e-12`` in float64: RK4 x1 9.8e-5, RK4 x2 7.7e-6,
SemiImplicitEuler x4 3.5e-2 (rad, m, rad/s, m/s). RK4 at the authors' cost is about 360 times more accurate than
their integrator.
"""

from __future__ import annotations

import math
from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from lagrange import systems
from lagrange.model.tree import Tree
from lagrange.integrate.solvers import RK4
from lagrange.tasks.base import (TaskSolver, TaskState, check_joints, check_number, check_schedule,
                                 check_state, wrap)
from lagrange.tasks.poles import AbstractPoleTask

__all__ = ["DiffRLCartpole", "POLE_INERTIA"]

POLE_INERTIA = 2.5 * (1.0**2 + 0.05**2) / 12.0
"""Inertia of the authors' 2.5 kg, 1 m x 0.05 m box pole about its centre of mass [kg m^2]."""


@final
class DiffRLCartpole(AbstractPoleTask):
    """The SHAC authors' cartpole swing-up (NVlabs/DiffRL); build it with :meth:`diffrl`.

    =====================  ======================================================================================
    state ``q`` / ``qd``   (x, q) / (dx, dq): cart position [m], pole angle relative to hanging down [rad]
    action (gear)          cart force ``1000 a`` N, ``a`` clipped to [-1, 1]
    observation (5,)       (x, dx, sin th, cos th, dth), ``th = q - pi`` (0 = upright, unwrapped inside sin/cos)
    reward per step        ``-(th^2 + 0.1 dth^2 + 0.05 x^2 + 0.1 dx^2)`` with ``th`` wrapped to (-pi, pi]; max 0
    episode                240 control steps of dt = 1/60 s (4 s), no early termination
    reset                  hanging down; ``x, q`` + U(-pi/2, pi/2) each, ``dx, dq`` + U(-0.25, 0.25) each
    =====================  ======================================================================================

    Attributes:
        chain (Tree): a cart-pole chain (:func:`lagrange.systems.cartpole`); the other fields are keyword-only, their
            defaults the authors'.
        dt (float): the control interval [s], > 0 (1/60).
        horizon (int): control steps per episode, >= 1 (240).
        substeps (int): steps of ``solver`` per interval, >= 1 (1).
        solver (TaskSolver): the integrator (``RK4()``; the authors' is ``SemiImplicitEuler()`` with 4 substeps).
        noise_q (float): the reset noise's half-width on ``x`` [m] and ``q`` [rad], >= 0 (pi/2).
        noise_qd (float): its half-width on ``dx`` [m/s] and ``dq`` [rad/s], >= 0 (0.25).
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=240, kw_only=True)
    substeps: int = eqx.field(static=True, default=1, kw_only=True)
    solver: TaskSolver = eqx.field(
        static=True, default=RK4(), kw_only=True)
    noise_q: float = eqx.field(static=True, default=math.pi / 2, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.25, kw_only=True)

    first_pole: ClassVar[int] = 1  # q = (x, theta): what lagrange.tasks.balanced / upright_error read
    name: ClassVar[str] = "diffrl_cartpole"

    def __check_init__(self):
        check_joints(self, ("prismatic", "revolute"))
        check_schedule(self)
        check_number(self, "noise_q", 0.0)
        check_number(self, "noise_qd", 0.0)

    @classmethod
    def diffrl(cls, *, cart_mass: float = 50.0, pole_mass: float = 2.5, pole_length: float = 1.0,
               pole_inertia: float = POLE_INERTIA, gear: float = 1000.0, dt: float = 1.0 / 60.0, horizon: int = 240,
               solver=RK4(), substeps: int = 1, noise_q: float = math.pi / 2,
               noise_qd: float = 0.25) -> DiffRLCartpole:
        """The SHAC authors' cartpole swing-up; every default is theirs (see the module docstring).

        Args:
            cart_mass: the cart's mass [kg].
            pole_mass: the pole's mass [kg].
            pole_length: the pole's length [m].
            pole_inertia: the pole's inertia about its centre of mass [kg m^2].
            gear: the force of a unit action [N].
            dt: the control interval [s].
            horizon: control steps per episode.
            solver: the integrator.
            substeps: its steps per interval.
            noise_q: the reset noise's half-width on ``x`` [m] and ``q`` [rad].
            noise_qd: on ``dx`` [m/s] and ``dq`` [rad/s].

        Raises:
            ValueError: naming a field out of range.
        """
        chain = systems.cartpole(cart_mass=cart_mass, pole_mass=pole_mass, pole_length=pole_length,
                                 pole_inertia=pole_inertia, gear=gear)
        return cls(chain, dt=float(dt), horizon=horizon, substeps=substeps, solver=solver, noise_q=float(noise_q),
                   noise_qd=float(noise_qd))

    @property
    def observation_size(self) -> int:
        return 5

    def reset(self, key: PRNGKeyArray) -> TaskState:
        """Hanging down, plus U(-noise_q, noise_q) on (x, q) and U(-noise_qd, noise_qd) on (dx, dq).

        Args:
            key: the PRNG key of the start.
        """
        dtype = jnp.result_type(self.chain.mass)
        kq, kv = jax.random.split(key)
        q = jax.random.uniform(kq, (2,), dtype, -self.noise_q, self.noise_q)
        qd = jax.random.uniform(kv, (2,), dtype, -self.noise_qd, self.noise_qd)
        return TaskState(q, qd)

    def observe(self, state: TaskState) -> Float[Array, " 5"]:
        """``(x, dx, sin th, cos th, dth)`` with ``th = q - pi``.

        Args:
            state: the state.
        """
        check_state(self, state, "observe")
        th = state.q[1:] - jnp.pi
        return jnp.concatenate([state.q[:1], state.qd[:1], jnp.sin(th), jnp.cos(th), state.qd[1:]])

    def reward(self, state: TaskState, action: Float[ArrayLike, " 1"], next_state: TaskState) -> Float[Array, ""]:
        """``-(th^2 + 0.1 dth^2 + 0.05 x^2 + 0.1 dx^2)`` of ``next_state`` (the authors' weights)."""
        del state, action
        check_state(self, next_state, "reward")
        q, qd = next_state.q, next_state.qd
        th = wrap(q[1] - jnp.pi)
        return -(th**2 + 0.1 * qd[1] ** 2 + 0.05 * q[0] ** 2 + 0.1 * qd[0] ** 2)
