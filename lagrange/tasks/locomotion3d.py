"""The SHAC paper's 3-D locomotion: DFlex's Ant and Humanoid (NVlabs/DiffRL) on exact spatial trees with penalty
contact.

Followed: NVlabs/DiffRL at commit 6b8d695567a30e774ed373572bb23c9db0ba7622 (the SHAC release): ``envs/ant.py``,
``envs/humanoid.py``, ``utils/load_utils.py`` (``parse_mjcf``), ``dflex/dflex/sim.py``, ``dflex/dflex/model.py``; the
assets ``envs/assets/ant.xml`` (read in the HaoxiangYou/DiffRL fork, which carries it unchanged) and
``humanoid.xml`` (the copy at ``dflex/dflex/envs/assets/humanoid.xml``, commit fb0e1e1); the SHAC configs
``examples/cfg/shac/ant.yaml`` and ``humanoid.yaml`` (commit 24a4996). The bodies are built here from the assets'
spheres and capsules with DFlex's mass and inertia formulas (:mod:`lagrange.tasks.dflex_trees`); nothing of
their code is copied.

:meth:`Ant.diffrl` and :meth:`Humanoid.diffrl` reproduce DFlex's physics as its code runs, quirks included:

=====================  =================================================================================================
bodies                 DFlex's loader: every shape at density 1000 kg/m^3 (the MJCF's ``density``, ``<default>``
                       classes, body ``quat`` s and gears ignored); a sphere of radius r weighs ``1000 (4/3) pi r^3``
                       with moment ``0.4 m r^2``; a capsule of radius r and length l (between its end points) weighs
                       ``1000 (4/3 pi r^3 + pi r^2 l)`` with the transverse moment of
                       :func:`lagrange.tasks.locomotion.capsule_mass_and_inertia` and the axial ``(m_c / 2 + 0.4 m_s)
                       r^2``; a body's shapes summed about their common centre of mass; DFlex's one link per joint is
                       a body with several hinges, each about its own anchor (the same motion)
root                   a free joint (MuJoCo's: ``q[0:3]`` the torso's position, ``q[3:7]`` its quaternion ``(w, x, y,
                       z)``, ``qd[0:3]`` its origin's velocity in the world, ``qd[3:6]`` its angular velocity in its
                       own frame); no armature, damping or limit on it (DFlex sets the free joint's armature to 0)
hinges                 the ant's: armature 0.05, damping 1; the humanoid's: stiffness (towards 0), damping and
                       armature from the asset; both plus DFlex's limit damping 10, applied at all times; outside its
                       range a hinge gets ``1000 (bound - q)``
actuation              the ant's ``200 a``, the humanoid's ``0.35 a`` times DFlex's strengths, ``a`` clipped to [-1, 1]
contact                ground ``z = 0``; the centre of every sphere and both end points of every capsule with its
                       radius; :class:`lagrange.PenaltyContact` (the ant's ke 4e4, kd 1e4, kf 3e3, mu 0.75; the
                       humanoid's 2e4, 5e3, 1e3, 0.75)
integration            1/60 s control steps of 16 (ant) or 48 (humanoid) semi-implicit Euler substeps, all forces
                       explicit, the mass matrix formed once per control step
                       (:data:`lagrange.tasks.locomotion.DFLEX_SOLVER`; the humanoid's recomputes each substep in the
                       backward pass, :data:`HUMANOID_SOLVER`)
episodes               1000 control steps; the reward of a transition is read on the state it lands in
=====================  =================================================================================================

The world is MuJoCo's, z up; DFlex turns the asset to y up (its start rotation -90 degrees about x), which changes
no physics: the observation's vectors are given here in the z-up world (DFlex's y-up components permuted), the torso's
quaternion in MuJoCo's order ``(w, x, y, z)`` relative to the upright start. DFlex's free joint moves its coordinates
by ``p += (v + w x p) h`` and ``quat += h/2 (w, 0) quat`` (then normalised), MuJoCo's (kept here) by ``p += v h`` and
the exponential map: the same method to first order in the step.
"""

import abc
import math
from collections.abc import Callable
from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
from equinox import AbstractVar
from jaxtyping import Array, ArrayLike, Bool, Float, PRNGKeyArray

from lagrange.math import spatial as al
from lagrange.model.joints import Free
from lagrange.integrate.solvers import SemiImplicitEuler
from lagrange.tasks.base import TaskSolver, TaskState, check_number, check_state
from lagrange.tasks.dflex_trees import ant_tree, humanoid_tree
from lagrange.tasks.locomotion import DFLEX_SOLVER, AbstractLocomotion
from lagrange.model.tree import Tree

__all__ = ["AbstractLocomotion3D", "Ant", "Humanoid", "HUMANOID_SOLVER"]

HUMANOID_SOLVER = SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True, checkpoint_substeps=True)
"""DFlex's integrator (:data:`~lagrange.tasks.locomotion.DFLEX_SOLVER`) with ``checkpoint_substeps``: the same steps;
SHAC's gradients through the humanoid's 48 substeps 1.6x faster on a CPU."""


def _quat_axis_angle(axis, angle):
    half = 0.5 * angle
    return jnp.concatenate([jnp.cos(half)[..., None], jnp.sin(half)[..., None] * axis], axis=-1)


class AbstractLocomotion3D(AbstractLocomotion):
    """A robot on a free joint rewarded for running along +x, DFlex's way (``envs/ant.py``, ``envs/humanoid.py``).

    The observation: the torso's height, its quaternion, its origin's velocity and its angular velocity in the world,
    the hinge angles, ``0.1 x`` the hinge velocities, the torso's up axis' vertical component, the heading (the
    torso's x axis on the ground) against the direction to a far target on the x axis, and the last action.

    Attributes:
        chain (Tree): the robot, its first joint a :class:`lagrange.Free`.
        start (tuple[float, ...]): the start coordinates before the noise (``nq`` of them).
        noise_pos (float): half-width of the uniform noise on the torso's start position [m].
        noise_angle (float): the largest angle of the start's random turn of the torso about a random axis [rad].
        noise_joints (float): half-width of the uniform noise on the hinge angles [rad].
        noise_qd (float): half-width of the uniform noise on every velocity, DFlex's (the torso's angular velocity
            and its world-frame twist).
        termination_height (float): the torso's height below which an episode ends [m].
        action_cost (float): the reward's ``-action_cost |a|^2``.
        target_x (float): the target's distance along x [m] (DFlex: 10000 for the ant).
    """

    noise_pos: AbstractVar[float]
    noise_angle: AbstractVar[float]
    noise_joints: AbstractVar[float]
    termination_height: AbstractVar[float]
    target_x: AbstractVar[float]
    ends_early: ClassVar[bool] = True
    planar: ClassVar[bool] = False
    noises: ClassVar[tuple[str, ...]] = ("noise_pos", "noise_angle", "noise_joints")

    def __check_init__(self):
        if not isinstance(self.chain.joints[0], Free):
            raise TypeError(f"{type(self).__name__}.chain's first joint must be a lagrange.Free, got "
                            f"{type(self.chain.joints[0]).__name__}")
        check_number(self, "termination_height", -math.inf)
        check_number(self, "target_x", 0.0, open_low=True)

    @property
    def observation_size(self) -> int:
        nj, m = self.chain.nq - 7, self.chain.m
        return 1 + 4 + 3 + 3 + 2 * nj + 2 + m

    def reset(self, key: PRNGKeyArray) -> TaskState:
        """DFlex's stochastic start: the start pose with ``U(-noise_pos, noise_pos)`` on the torso's position, the
        torso turned (in its own frame) by ``U(-noise_angle, noise_angle)`` about a random axis (a uniform point of
        the cube ``[-1/2, 1/2]^3`` normalised), ``U(-noise_joints, noise_joints)`` on every hinge; every one of
        DFlex's velocities ``U(-noise_qd, noise_qd)`` (the torso's world angular velocity ``w`` and its world twist
        ``v``, turned into MuJoCo's: the origin's velocity ``v + w x p`` and ``R^T w``); the last action zero.

        Args:
            key: the PRNG key it is drawn with.
        """
        dtype = jnp.result_type(self.chain.mass)
        kp, ka, kx, kj, kv = jax.random.split(key, 5)
        start = jnp.asarray(self.start, dtype)
        pos = start[:3] + jax.random.uniform(kp, (3,), dtype, -self.noise_pos, self.noise_pos)
        angle = jax.random.uniform(ka, (), dtype, -self.noise_angle, self.noise_angle)
        axis = jax.random.uniform(kx, (3,), dtype, -0.5, 0.5)
        turn = _quat_axis_angle(axis / jnp.linalg.norm(axis), angle)
        quat = al.quat_multiply(start[3:7], turn)
        nj = self.chain.nq - 7
        joints = start[7:] + jax.random.uniform(kj, (nj,), dtype, -self.noise_joints, self.noise_joints)
        v = jax.random.uniform(kv, (self.chain.nv,), dtype, -self.noise_qd, self.noise_qd)
        w, twist = v[:3], v[3:6]
        R = al.quat_to_matrix(quat)
        qd = jnp.concatenate([twist + jnp.cross(w, pos), al.tmatvec(R, w), v[6:]])
        return TaskState(jnp.concatenate([pos, quat, joints]), qd, jnp.zeros(self.chain.m, dtype))

    def _frame(self, q):
        """The torso's rotation (world from torso), ``(..., 3, 3)``."""
        return al.quat_to_matrix(al.normalize_quat(q[..., 3:7]))

    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """``[height, quaternion (w, x, y, z), velocity (3), angular velocity (3), hinge angles, 0.1 hinge velocities,
        up_z, heading . target direction, last action]``, the vectors in the world frame (z up).

        Args:
            state: one state (with its ``action``).
        """
        check_state(self, state)
        if state.action is None:
            cls = type(self).__name__
            raise ValueError(f"{cls}.observe: state.action is None; this task observes the last action: start from "
                             f"{cls}.reset(key), or pass TaskState(q, qd, action)")
        q, qd = state.q, state.qd
        R = self._frame(q)
        to_target = jnp.stack([self.target_x - q[0], -q[1], jnp.zeros_like(q[0])])
        direction = to_target / jnp.linalg.norm(to_target)
        heading = jnp.sum(R[:, 0] * direction)
        return jnp.concatenate([q[2:3], q[3:7], qd[0:3], al.matvec(R, qd[3:6]), q[7:], 0.1 * qd[6:],
                                R[2:3, 2], heading[None], state.action])

    def reward(self, state: TaskState, action: Float[ArrayLike, " m"], next_state: TaskState) -> Float[Array, ""]:
        """DFlex's reward of the state the step lands in: ``v_x + 0.1 up_z + heading + height_reward(height) -
        action_cost |a|^2`` (each task's table), the action clipped to [-1, 1] here."""
        obs = self.observe(next_state)
        nj = self.chain.nq - 7
        return (obs[5] + 0.1 * obs[11 + 2 * nj] + obs[12 + 2 * nj] + self.height_reward(obs[0])
                - self._action_cost(action))

    @abc.abstractmethod
    def height_reward(self, height: Float[Array, ""]) -> Float[Array, ""]:
        """The reward's term of the torso's height [m].

        Args:
            height: the torso's height.
        """

    def terminated(self, state: TaskState) -> Bool[Array, ""]:
        """The robot fell: the torso below ``termination_height``.

        Args:
            state: one state.
        """
        return state.q[2] < self.termination_height

    def succeeded(self, q: Float[ArrayLike, "*batch T nq"]) -> Bool[Array, " *batch"]:
        """The torso never fell below ``termination_height``.

        Args:
            q: a trajectory of coordinates, shape ``(*batch, T, nq)``.
        """
        return jnp.all(jnp.asarray(q)[..., 2] >= self.termination_height, axis=-1)

    def track(self, q: Float[ArrayLike, "*batch nq"]) -> dict[str, Float[Array, " *batch"]]:
        """What a gait plot shows: the torso's x [m], height [m] and tilt (the angle of its z axis from the
        vertical) [rad].

        Args:
            q: coordinates, shape ``(*batch, nq)``.
        """
        q = jnp.asarray(q)
        up = self._frame(q)[..., 2, 2]
        return {"x [m]": q[..., 0], "height [m]": q[..., 2], "tilt [rad]": jnp.arccos(jnp.clip(up, -1.0, 1.0))}


@final
class Ant(AbstractLocomotion3D):
    """DFlex's ant (the SHAC paper's); build it with :meth:`diffrl`.

    =====================  =============================================================================================
    state ``q`` / ``qd``   (15) the torso's position and quaternion ``(w, x, y, z)``, 8 hinge angles (hip, ankle of each
                           leg: front left, front right, back left, back right); (14) MuJoCo's velocities
    action (gear)          the 8 hinge torques ``200 a`` N m, ``a`` clipped to [-1, 1]
    observation (37)       height, quaternion (4), velocity (3), angular velocity (3, world), hinge angles (8),
                           ``0.1 x`` hinge velocities (8), up_z, heading . target, last action (8)
    reward per step        ``v_x + 0.1 up_z + heading + (height - 0.27)`` of the state the step lands in
    early end              height < 0.27 m, after the step's reward
    episode                1000 control steps of 1/60 s (16.7 s)
    reset                  torso at (0, 0, 0.75) + U(-0.1, 0.1), turned up to 7.5 degrees about a random axis; hinges
                           (0, 1, 0, -1, 0, -1, 0, 1) + U(-0.2, 0.2) rad; DFlex's velocities U(-0.25, 0.25)
    bodies (kg)            torso 96.78 (its sphere 65.45), each thigh 7.83, each foot 13.52 (182.18)
    =====================  =============================================================================================
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=1000, kw_only=True)
    substeps: int = eqx.field(static=True, default=16, kw_only=True)
    solver: TaskSolver = eqx.field(static=True, default=DFLEX_SOLVER, kw_only=True)
    start: tuple[float, ...] = eqx.field(static=True, default=(0.0, 0.0, 0.75, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0,
                                                                -1.0, 0.0, -1.0, 0.0, 1.0), kw_only=True)
    noise_pos: float = eqx.field(static=True, default=0.1, kw_only=True)
    noise_angle: float = eqx.field(static=True, default=math.pi / 24, kw_only=True)
    noise_joints: float = eqx.field(static=True, default=0.2, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.25, kw_only=True)
    termination_height: float = eqx.field(static=True, default=0.27, kw_only=True)
    action_cost: float = eqx.field(static=True, default=0.0, kw_only=True)
    target_x: float = eqx.field(static=True, default=10000.0, kw_only=True)

    name: ClassVar[str] = "ant"
    model: ClassVar[Callable[[], Tree]] = staticmethod(ant_tree)

    def height_reward(self, height: Float[Array, ""]) -> Float[Array, ""]:
        """``height - termination_height`` (DFlex's ant).

        Args:
            height: the torso's height [m].
        """
        return height - self.termination_height


@final
class Humanoid(AbstractLocomotion3D):
    """DFlex's humanoid (the SHAC paper's); build it with :meth:`diffrl`.

    =====================  =============================================================================================
    state ``q`` / ``qd``   (28) the torso's position and quaternion ``(w, x, y, z)``, 21 hinge angles (abdomen z, y, x;
                           right hip x, z, y, knee, ankle y, x; the left leg's; right shoulder 1, 2, elbow; the left
                           arm's); (27) MuJoCo's velocities
    action (gear)          21 hinge torques ``0.35 a x`` DFlex's strengths (abdomen 70 N m, hips 70 and 210 about y,
                           knees 140, ankles 35, shoulders 35, elbows 70), ``a`` clipped to [-1, 1]
    observation (76)       height, quaternion (4), velocity (3), angular velocity (3, world), hinge angles (21),
                           ``0.1 x`` hinge velocities (21), up_z, heading . target, last action (21)
    reward per step        ``v_x + 0.1 up_z + heading + H(height) - 0.002 |a|^2`` of the state the step lands in, with
                           ``x = clip(height - 0.84, -1, 0.1)``, ``H = -200 x^2`` for ``x < 0``, else ``10 x``
    early end              height < 0.74 m, after the step's reward
    episode                1000 control steps of 1/60 s, 48 substeps each
    reset                  torso at (0, 0, 1.35) + U(-0.1, 0.1), turned up to 7.5 degrees about a random axis; hinges
                           U(-0.2, 0.2) rad; DFlex's velocities U(-0.25, 0.25)
    contact                the spheres' centres and the capsules' ends (35 points), ke 2e4, kd 5e3, kf 1e3, mu 0.75
    =====================  =============================================================================================

    Attributes:
        standing_height (float): the height term's level [m] (DFlex: 0.84).
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=1000, kw_only=True)
    substeps: int = eqx.field(static=True, default=48, kw_only=True)
    solver: TaskSolver = eqx.field(static=True, default=HUMANOID_SOLVER, kw_only=True)
    start: tuple[float, ...] = eqx.field(static=True, default=(0.0, 0.0, 1.35, 1.0, 0.0, 0.0, 0.0) + (0.0,) * 21,
                                         kw_only=True)
    noise_pos: float = eqx.field(static=True, default=0.1, kw_only=True)
    noise_angle: float = eqx.field(static=True, default=math.pi / 24, kw_only=True)
    noise_joints: float = eqx.field(static=True, default=0.2, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.25, kw_only=True)
    termination_height: float = eqx.field(static=True, default=0.74, kw_only=True)
    action_cost: float = eqx.field(static=True, default=0.002, kw_only=True)
    target_x: float = eqx.field(static=True, default=200.0, kw_only=True)
    standing_height: float = eqx.field(static=True, default=0.84, kw_only=True)

    name: ClassVar[str] = "humanoid"
    model: ClassVar[Callable[[], Tree]] = staticmethod(humanoid_tree)

    def __check_init__(self):
        check_number(self, "standing_height", -math.inf)

    def height_reward(self, height: Float[Array, ""]) -> Float[Array, ""]:
        """DFlex's humanoid's: ``-200 x^2`` for ``x = clip(height - standing_height, -1, 0.1) < 0``, else ``10 x``.

        Args:
            height: the torso's height [m].
        """
        x = jnp.clip(height - self.standing_height, -1.0, 0.1)
        return jnp.where(x < 0, -200.0 * x * x, 10.0 * x)
