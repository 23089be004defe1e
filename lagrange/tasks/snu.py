"""The SHAC paper's muscle-actuated humanoid ("SNU Humanoid", "Humanoid MTU"): MASS's lower body driven by 152
muscles (:func:`lagrange.tasks.snu_tree.snu_tree`), rewarded for walking along +x, as DFlex's ``envs/snu_humanoid.py``
(NVlabs/DiffRL 6b8d695) runs it; nothing of its code is copied.

=====================  ================================================================================================
state ``q`` / ``qd``   (29) the pelvis's position and quaternion ``(w, x, y, z)``, the right femur's ball quaternion,
                       the knee, the talus's quaternion, the two toes, the left leg's the same; (24) MuJoCo's
                       velocities (the pelvis's linear velocity in the world and angular velocity in its frame, each
                       ball's angular velocity in its body's frame)
action                 152 muscle activations: ``a`` clipped to [-1, 1], the activation ``a / 2 + 1/2`` in [0, 1], the
                       tension ``activation x 0.36 f0``
observation (53)       the pelvis's height, its quaternion (4), its origin's velocity (3) and angular velocity (3) in
                       the world, the joints' coordinates (22: four ball quaternions and seven angles), ``0.1 x`` the
                       joints' velocities (18), up_z (the body's up axis, MASS's y, against the world's), the heading
                       (MASS's z, the way the body faces) against the direction to a target 10 km along x
reward per step        ``v_x + 0.1 up_z + heading - 0.001 sum(activations)`` of the state the step lands in (DFlex
                       computes a height term and does not add it)
early end              the pelvis below 0.46 m, after the step's reward
episode                1000 control steps of 1/60 s, 48 semi-implicit Euler substeps each, all forces explicit, the mass
                       matrix formed anew every 8 substeps (DFlex's ``MM_caching_frequency``)
reset                  the start pose (legs straight, the pelvis's joint at (0, 0, 1) m, facing +x) with U(-0.1, 0.1)
                       on the pelvis's position, the pelvis turned in its own frame by up to 7.5 degrees about a random
                       axis, every one of DFlex's velocities U(-0.25, 0.25); no noise on the joints' angles
=====================  ================================================================================================

DFlex's world is y up and its free joint's velocity a twist in the world; this one is z up (MASS's y the world's z at
the start) with MuJoCo's conventions, the same physics. DFlex's balls turn with the angular velocity in the parent's
frame, this one's in the body's: at the start pose (every joint at rest) the two are the same, so the reset's noise is
DFlex's. DFlex also ends an episode, and zeroes that step's reward, on a non-finite state or one beyond 1e6; here
:func:`lagrange.simulate` and the trainers report a non-finite state instead.
"""

import math
from collections.abc import Callable
from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from lagrange.integrate.solvers import SemiImplicitEuler
from lagrange.model.tree import Tree
from lagrange.tasks.base import TaskSolver, TaskState, check_state
from lagrange.tasks.locomotion3d import AbstractLocomotion3D
from lagrange.tasks.snu_tree import START, START_QUAT, snu_tree

__all__ = ["SNU_SOLVER", "SNUHumanoid"]

SNU_SOLVER = SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True, mass_matrix_every=8,
                               checkpoint_substeps=True)
"""DFlex's SNU integrator: semi-implicit Euler, every force explicit, ``M`` formed every 8 of the 48 substeps; the
substeps recomputed in the backward pass (the same values, less memory)."""


@final
class SNUHumanoid(AbstractLocomotion3D):
    """DFlex's SNU humanoid (the SHAC paper's muscle-actuated one); build it with :meth:`diffrl` (the module docstring
    has its table).

    Attributes:
        activation_cost (float): the reward's ``-activation_cost sum(activations)`` (DFlex: 0.001).
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=1000, kw_only=True)
    substeps: int = eqx.field(static=True, default=48, kw_only=True)
    solver: TaskSolver = eqx.field(static=True, default=SNU_SOLVER, kw_only=True)
    start: tuple[float, ...] = eqx.field(
        static=True, default=START + START_QUAT + (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0) * 2,
        kw_only=True)
    noise_pos: float = eqx.field(static=True, default=0.1, kw_only=True)
    noise_angle: float = eqx.field(static=True, default=math.pi / 24, kw_only=True)
    noise_joints: float = eqx.field(static=True, default=0.0, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.25, kw_only=True)
    termination_height: float = eqx.field(static=True, default=0.46, kw_only=True)
    action_cost: float = eqx.field(static=True, default=0.0, kw_only=True)
    activation_cost: float = eqx.field(static=True, default=0.001, kw_only=True)
    target_x: float = eqx.field(static=True, default=10000.0, kw_only=True)

    name: ClassVar[str] = "snu_humanoid"
    model: ClassVar[Callable[[], Tree]] = staticmethod(snu_tree)

    def __check_init__(self):
        if self.noise_joints != 0.0:
            raise ValueError("SNUHumanoid.noise_joints must be 0: the joints' coordinates hold quaternions, which a "
                             "uniform noise would leave unnormalised (DFlex's SNU task has no joint noise)")
        if not self.chain.muscles:
            raise ValueError("SNUHumanoid.chain must have muscles (its actions are their activations)")

    @property
    def observation_size(self) -> int:
        return 1 + 4 + 3 + 3 + (self.chain.nq - 7) + (self.chain.nv - 6) + 2

    def controls(self, action: Float[Array, " m"]) -> Float[Array, " m"]:
        """The muscles' activations ``a / 2 + 1/2`` in ``[0, 1]`` of the clipped action ``a``.

        Args:
            action: one action, clipped to [-1, 1], shape ``(m,)``.
        """
        return 0.5 * action + 0.5

    def reset(self, key: PRNGKeyArray) -> TaskState:
        """:meth:`AbstractLocomotion3D.reset`'s noisy start (no noise on the joints), without a last action (this
        task does not observe it).

        Args:
            key: the PRNG key it is drawn with.
        """
        s = super().reset(key)
        return TaskState(s.q, s.qd)

    def _axes(self, q):
        """The body's up axis (MASS's y) and heading (MASS's z) in the world, from the pelvis's quaternion."""
        R = self._frame(q)
        return R[..., :, 1], R[..., :, 2]

    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """``[height, quaternion (w, x, y, z), velocity (3), angular velocity (3), joint coordinates (22), 0.1 joint
        velocities (18), up_z, heading . target direction]``, the vectors in the world frame (z up).

        Args:
            state: one state.
        """
        check_state(self, state)
        q, qd = state.q, state.qd
        R = self._frame(q)
        up, heading = self._axes(q)
        to_target = jnp.stack([self.target_x + self.start[0] - q[0], self.start[1] - q[1], jnp.zeros_like(q[0])])
        direction = to_target / jnp.linalg.norm(to_target)
        return jnp.concatenate([q[2:3], q[3:7], qd[0:3], R @ qd[3:6], q[7:], 0.1 * qd[6:], up[2:3],
                                jnp.sum(heading * direction)[None]])

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """DFlex's reward of the state the step lands in: ``v_x + 0.1 up_z + heading - activation_cost
        sum(activations)``, the activations those of the action clipped to [-1, 1].

        Args:
            state: the state before.
            action: the action, shape ``(m,)``.
            next_state: the state after.
        """
        obs = self.observe(next_state)
        activations = self.controls(jnp.clip(action, -1.0, 1.0))
        return obs[5] + 0.1 * obs[-2] + obs[-1] - self.activation_cost * jnp.sum(activations)

    def height_reward(self, height: Float[Array, ""]) -> Float[Array, ""]:
        """None: DFlex computes a height term for this task and does not add it (0).

        Args:
            height: the pelvis's height [m].
        """
        return jnp.zeros_like(height)

    def track(self, q: Float[ArrayLike, "*batch nq"]) -> dict[str, Float[Array, " *batch"]]:
        """What a gait plot shows: the pelvis's x [m], height [m] and tilt (its up axis from the vertical) [rad].

        Args:
            q: coordinates, shape ``(*batch, nq)``.
        """
        q = jnp.asarray(q)
        up = self._axes(q)[0][..., 2]
        return {"x [m]": q[..., 0], "height [m]": q[..., 2], "tilt [rad]": jnp.arccos(jnp.clip(up, -1.0, 1.0))}
