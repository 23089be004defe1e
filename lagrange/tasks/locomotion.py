"""The SHAC paper's planar locomotion: DFlex's Hopper and Cheetah (NVlabs/DiffRL) on exact trees with penalty contact.

Followed: NVlabs/DiffRL at commit 6b8d695567a30e774ed373572bb23c9db0ba7622 (the SHAC release): ``envs/hopper.py``,
``envs/cheetah.py``, ``utils/load_utils.py``, ``dflex/dflex/sim.py``, ``dflex/dflex/model.py`` and the SHAC configs
``examples/cfg/shac/hopper.yaml``, ``cheetah.yaml``. The bodies are built here from their capsules (the geometry of the
authors' MJCF assets) with DFlex's mass and inertia formulas; nothing of their code is copied.

:meth:`Hopper.diffrl` and :meth:`Cheetah.diffrl` reproduce DFlex's physics as its code runs, quirks included (each
task's table lists them):

=====================  =================================================================================================
bodies                 links from capsules at density 1000 kg/m^3 (the MJCF's ``mass``, ``settotalmass``, inertials
                       ignored): a capsule of radius r and length l weighs ``1000 (4/3 pi r^3 + pi r^2 l)`` and has the
                       transverse moment ``m_c (r^2/4 + l^2/12) + m_s (0.4 r^2 + 0.375 r l + l^2/4)`` about its centre
                       (DFlex's, after ODE); the hopper weighs 15.82 kg, the cheetah 21.18 kg (Gymnasium's: 14)
root                   a slide along x, a slide along z, a hinge: massless links, then the torso (``q[0:3]``)
actuation              ``200 a`` on every actuated joint, ``a`` clipped to [-1, 1] (the MJCF gears unused)
joints                 every dof, root included: armature (hopper 1.0, cheetah 0.1), the joint's own damping plus
                       DFlex's limit damping 10 (applied at all times), springs towards 0 (cheetah); outside its range a
                       joint gets ``1000 (bound - q)``
contact                ground ``z = 0``, every capsule's two end points with its radius (hopper 8, cheetah 16),
                       :class:`lagrange.PenaltyContact` ke 2e4, kd 1e3, kf 1e3, mu 0.9 (hopper) / 1.0 (cheetah)
integration            1/60 s control steps of 16 semi-implicit Euler substeps, all forces explicit, the mass matrix
                       formed once per control step and held over its substeps (the SHAC configs'
                       ``MM_caching_frequency: 16``): ``SemiImplicitEuler(implicit_damping=False,
                       hold_mass_matrix=True)``
episodes               1000 control steps; the reward of a transition is read on the state it lands in
=====================  =================================================================================================

The plane is MuJoCo's x-z plane (DFlex turns it to y-up; nothing changes in the plane); the hinges turn about the
MJCF's axes, so ``q`` and ``qd`` are DFlex's joint coordinates and velocities, ``q[1]`` the root's height above its
start (DFlex's observation ``rootz``).
"""

import abc
import math
from collections.abc import Callable
from typing import ClassVar, Self, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar, AbstractVar
from jaxtyping import Array, ArrayLike, Bool, Float, PRNGKeyArray

from lagrange.chain import Chain, Link
from lagrange.model.tree import Tree
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits
from lagrange.integrate.solvers import SemiImplicitEuler
from lagrange.tasks.base import AbstractTask, TaskSolver, TaskState, check_number, check_schedule, check_state

__all__ = ["AbstractLocomotion", "AbstractPlanarLocomotion", "Hopper", "Cheetah", "capsule_mass_and_inertia",
           "cheetah_chain", "hopper_chain", "DFLEX_SOLVER"]

DFLEX_SOLVER = SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True)
"""DFlex's integrator as the SHAC configs run it: explicit forces, the mass matrix held over a control step."""

DENSITY = 1000.0
LIMIT_KE, LIMIT_KD = 1000.0, 10.0  # DFlex's parse_mjcf(limit_ke, limit_kd) for both tasks


def capsule_mass_and_inertia(radius: float, length: float, density: float = DENSITY) -> tuple[float, float]:
    """DFlex's capsule (``dflex/dflex/model.py``, ``compute_capsule_inertia``): the mass of a cylinder of ``length``
    and two hemispheres, and the moment of inertia about the centre across the axis (the planar one for a capsule
    lying in the plane).

    Args:
        radius: the capsule's radius [m].
        length: its cylinder's length, between the end points [m].
        density: [kg/m^3].

    Returns:
        ``(mass [kg], inertia [kg m^2])``.
    """
    ms = density * 4.0 / 3.0 * math.pi * radius**3
    mc = density * math.pi * radius**2 * length
    inertia = mc * (0.25 * radius**2 + length**2 / 12) + ms * (0.4 * radius**2 + 0.375 * radius * length
                                                               + 0.25 * length**2)
    return ms + mc, inertia


def _capsule(pos, angle, half):
    """End points of an MJCF capsule centred at ``pos`` (x, z) whose axis (local z) is turned by ``angle`` about y."""
    axis = np.array([math.sin(angle), math.cos(angle)]) * half
    return np.asarray(pos, float) - axis, np.asarray(pos, float) + axis


def _link(joint: str, capsules, radius: float, **kw) -> Link:
    """A link whose body is the ``capsules`` (pairs of end points in its frame, (x, z)), all of ``radius``: mass,
    centre of mass and planar inertia by DFlex's formulas; each capsule's end points its contact points."""
    parts = [(*capsule_mass_and_inertia(radius, float(np.hypot(*(b - a)))), (a + b) / 2) for a, b in capsules]
    mass = sum(m for m, _, _ in parts)
    centre = sum(m * c for m, _, c in parts) / mass if mass > 0 else np.zeros(2)
    inertia = sum(i + m * float(np.sum((c - centre) ** 2)) for m, i, c in parts)
    contacts = [(float(p[0]), float(p[1]), radius) for pair in capsules for p in pair]
    # the frame's local x along e, local z against d: the centre (x, z) is com_normal = x, com = -z
    return Link(joint, mass, 0.0, com=float(-centre[1]), com_normal=float(centre[0]), inertia=inertia,
                contacts=contacts, **kw)


def _root(armature: float, *, x_at=None, z_at=None) -> list[Link]:
    """The planar floating base: a slide along x (its joint at ``x_at`` in the world) and one along z (at ``z_at`` on
    the first), both massless; the torso's hinge comes next. Their own damping is 0; DFlex's limit damping acts on
    them too."""
    return [Link("prismatic", 0.0, armature=armature, damping=LIMIT_KD, attach=x_at),
            Link("prismatic", 0.0, axis=math.pi / 2, armature=armature, damping=LIMIT_KD, attach=z_at)]


def hopper_chain() -> Chain:
    """DFlex's hopper (the SHAC release's ``envs/assets/hopper.xml`` as its loader reads it): rootx, rootz (its joint
    1.25 m above rootx's), the torso's hinge (turning about +y), thigh, leg and foot hinges (about -y), ranges
    thigh/leg [-2.61799, 0], foot [-0.785398, 0.785398], damping 2 + 10 on the three, armature 1 on every dof."""
    arm, kd = 1.0, 2.0 + LIMIT_KD
    links = _root(arm, z_at=(0.0, 1.25)) + [
        _link("revolute", [(np.array([0.0, -0.2]), np.array([0.0, 0.2]))], 0.05, sense=-1, armature=arm,
              damping=LIMIT_KD),
        _link("revolute", [(np.array([0.0, -0.45]), np.array([0.0, 0.0]))], 0.05, parent=2, attach=(0.0, -0.2),
              armature=arm, damping=kd, gear=200.0, range=(-2.61799, 0.0)),
        _link("revolute", [(np.array([0.0, -0.5]), np.array([0.0, 0.0]))], 0.04, attach=(0.0, -0.45),
              armature=arm, damping=kd, gear=200.0, range=(-2.61799, 0.0)),
        _link("revolute", [(np.array([0.255, 0.0]), np.array([-0.135, 0.0]))], 0.06, attach=(0.0, -0.5),
              armature=arm, damping=kd, gear=200.0, range=(-0.785398, 0.785398)),
    ]
    return Chain(links, gravity=9.81, contact=PenaltyContact(2e4, 1e3, 1e3, 0.9), limits=PenaltyLimits(LIMIT_KE))


# the cheetah's legs (half_cheetah.xml of the SHAC release): (parent, attach, capsule centre, turn, half length,
# stiffness, damping, range); every hinge turns about +y
_CHEETAH_LEGS = (
    (2, (-0.5, 0.0), (0.1, -0.13), -3.8, 0.145, 240.0, 6.0, (-0.52, 1.05)),     # bthigh
    (3, (0.16, -0.25), (-0.14, -0.07), -2.03, 0.15, 180.0, 4.5, (-0.785, 0.785)),  # bshin
    (4, (-0.28, -0.14), (0.03, -0.097), -0.27, 0.094, 120.0, 3.0, (-0.4, 0.785)),  # bfoot
    (2, (0.5, 0.0), (-0.07, -0.12), 0.52, 0.133, 180.0, 4.5, (-1.5, 0.8)),         # fthigh
    (6, (-0.14, -0.24), (0.065, -0.09), -0.6, 0.106, 120.0, 3.0, (-1.2, 1.1)),     # fshin
    (7, (0.13, -0.18), (0.045, -0.07), -0.6, 0.07, 60.0, 1.5, (-3.1, -0.3)),       # ffoot
)


def cheetah_chain() -> Chain:
    """DFlex's half-cheetah (the SHAC release's ``envs/assets/half_cheetah.xml`` as its loader reads it): the root's x
    slide 1 m above the ground, the torso and head capsules on the root hinge, a back and a front leg of three
    hinges each branching at the torso; springs towards 0, the joint's damping plus 10, armature 0.1 everywhere."""
    arm, r = 0.1, 0.046
    links = _root(arm, x_at=(0.0, 1.0))
    torso = (np.array([-0.5, 0.0]), np.array([0.5, 0.0]))
    head = _capsule((0.6, 0.1), 0.87, 0.15)
    links.append(_link("revolute", [torso, head], r, sense=-1, armature=arm, damping=LIMIT_KD))
    for parent, attach, centre, turn, half, k, kd, rng in _CHEETAH_LEGS:
        links.append(_link("revolute", [_capsule(centre, turn, half)], r, sense=-1, parent=parent, attach=attach,
                           armature=arm, damping=kd + LIMIT_KD, stiffness=k, gear=200.0, range=rng))
    return Chain(links, gravity=9.81, contact=PenaltyContact(2e4, 1e3, 1e3, 1.0), limits=PenaltyLimits(LIMIT_KE))


class AbstractLocomotion(AbstractTask):
    """A robot on a floating base rewarded for running forward, as DFlex's tasks run it (``envs/hopper.py``,
    ``cheetah.py``, ``ant.py``, ``humanoid.py``): the planar hopper and cheetah (:class:`AbstractPlanarLocomotion`)
    and the 3-D ant and humanoid (:class:`lagrange.tasks.AbstractLocomotion3D`). Each is built on DFlex's robot by
    :meth:`diffrl`, starts from ``start`` plus uniform noise, pays ``action_cost |a|^2`` and tells a gait plot what to
    show (:meth:`track`).

    Attributes:
        chain (Tree): the robot.
        dt (float): the control interval [s] (DFlex: 1/60).
        horizon (int): control steps per episode (DFlex: 1000).
        substeps (int): solver steps per control interval.
        solver (TaskSolver): the integrator (DFlex's: :data:`DFLEX_SOLVER`).
        start (tuple[float, ...]): the start coordinates before the noise (``nq`` of them).
        noise_qd (float): half-width of the uniform noise on every start velocity.
        action_cost (float): the reward's ``-action_cost |a|^2``.
        name (ClassVar[str]): a display name.
        model (ClassVar): DFlex's robot, built (:func:`hopper_chain`, :func:`lagrange.tasks.dflex_trees.ant_tree`, ...).
        planar (ClassVar[bool]): whether the robot moves in a plane (its ``chain`` must then be planar).
        noises (ClassVar[tuple[str, ...]]): the fields of the start's noise, numbers >= 0.
    """

    chain: AbstractVar[Tree]
    start: AbstractVar[tuple[float, ...]]
    noise_qd: AbstractVar[float]
    action_cost: AbstractVar[float]
    name: AbstractClassVar[str]
    model: AbstractClassVar[Callable[[], Tree]]
    planar: AbstractClassVar[bool]
    noises: AbstractClassVar[tuple[str, ...]]

    def __check_init__(self):
        check_schedule(self, self.planar)
        cls = type(self).__name__
        if len(self.start) != self.chain.nq:
            raise ValueError(f"{cls}.start must have one entry per coordinate ({self.chain.nq}), got {self.start!r}")
        for field in (*self.noises, "noise_qd", "action_cost"):
            check_number(self, field, 0.0)

    @classmethod
    def diffrl(cls, **overrides) -> Self:
        """The SHAC paper's task as DFlex runs it, on DFlex's robot (:attr:`model`); ``overrides`` replace fields
        (``solver=lg.SemiImplicitEuler()`` for exact dynamics without DFlex's held mass matrix, ``horizon=``, ...).

        Raises:
            ValueError, TypeError: naming a field out of range.
        """
        return cls(cls.model(), **overrides)

    @abc.abstractmethod
    def track(self, q: Float[ArrayLike, "*batch nq"]) -> dict[str, Float[Array, " *batch"]]:
        """What a gait plot shows of coordinates ``q`` (``(*batch, nq)``): the body's x [m], its height [m] and its
        pitch or tilt [rad], by name."""

    def _action_cost(self, action) -> Float[Array, ""]:
        a = jnp.clip(action, -1.0, 1.0)
        return self.action_cost * jnp.sum(a * a)


class AbstractPlanarLocomotion(AbstractLocomotion):
    """A planar robot on a floating base (``q[0]`` the root's x, ``q[1]`` its height above the start, ``q[2]`` the
    torso's pitch) rewarded for running forward; DFlex's observation ``(q[1:], qd)``.

    Attributes:
        noise_q (float): half-width of the uniform noise on every start coordinate.
    """

    noise_q: AbstractVar[float]
    planar: ClassVar[bool] = True
    noises: ClassVar[tuple[str, ...]] = ("noise_q",)

    @property
    def observation_size(self) -> int:
        return 2 * self.chain.nv - 1

    def reset(self, key: PRNGKeyArray) -> TaskState:
        """The start pose plus ``U(-noise_q, noise_q)`` on every coordinate, velocities ``U(-noise_qd, noise_qd)``.

        Args:
            key: the PRNG key it is drawn with.
        """
        dtype = jnp.result_type(self.chain.mass)
        kq, kv = jax.random.split(key)
        n = self.chain.nv
        q = jnp.asarray(self.start, dtype) + jax.random.uniform(kq, (n,), dtype, -self.noise_q, self.noise_q)
        qd = jax.random.uniform(kv, (n,), dtype, -self.noise_qd, self.noise_qd)
        return TaskState(q, qd)

    def observe(self, state: TaskState) -> Float[Array, " observation_size"]:
        """``(q[1:], qd)``: the root's height and pitch, the joint angles, and every velocity (DFlex's, unclipped).

        Args:
            state: one state.
        """
        check_state(self, state)
        return jnp.concatenate([state.q[1:], state.qd])

    def track(self, q: Float[ArrayLike, "*batch n"]) -> dict[str, Float[Array, " *batch"]]:
        """What a gait plot shows: the root's x [m], its height above the start [m] and the torso's pitch [rad].

        Args:
            q: coordinates, shape ``(*batch, n)``.
        """
        q = jnp.asarray(q)
        return {"x [m]": q[..., 0], "height above start [m]": q[..., 1], "pitch [rad]": q[..., 2]}


@final
class Hopper(AbstractPlanarLocomotion):
    """DFlex's hopper (the SHAC paper's); build it with :meth:`diffrl`.

    =====================  =============================================================================================
    state ``q`` / ``qd``   (x, z, pitch, thigh, leg, foot) [m, m, rad...]: ``z`` the root's height above its start
                           (the torso's hinge at 1.25 + z m), pitch about +y; and their rates
    action (gear)          thigh, leg, foot torques ``200 a`` N m, ``a`` clipped to [-1, 1]
    observation (11)       ``(q[1:], qd)``: z, pitch, 3 joint angles, 6 velocities, unclipped
    reward per step        ``qd[0] + H(z) + 1 - (pitch / (pi/6))^2 - 0.1 |a|^2`` of the state the step lands in, with
                           ``h = clip(z + 0.30, -1, 0.3)``, ``H = -200 h^2`` for ``h < 0``, else ``h``
    early end              ``z < -0.45`` (the torso's hinge below 0.80 m), after the step's reward
    episode                1000 control steps of 1/60 s (16.7 s)
    reset                  ``q`` = 0 + U(-0.05, 0.05) on every coordinate, ``qd`` = U(-0.05, 0.05); the foot 4 cm above
                           the ground
    bodies (kg)            torso 3.665, thigh 4.058, leg 2.781, foot 5.316 (15.82); DFlex's foot is centred 0.06 m
                           from its hinge (Gymnasium's 0.065)
    =====================  =============================================================================================

    Attributes:
        termination_height (float): the early end's height [m] (DFlex: -0.45).
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=1000, kw_only=True)
    substeps: int = eqx.field(static=True, default=16, kw_only=True)
    solver: TaskSolver = eqx.field(static=True, default=DFLEX_SOLVER, kw_only=True)
    start: tuple[float, ...] = eqx.field(static=True, default=(0.0,) * 6, kw_only=True)
    noise_q: float = eqx.field(static=True, default=0.05, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.05, kw_only=True)
    action_cost: float = eqx.field(static=True, default=0.1, kw_only=True)
    termination_height: float = eqx.field(static=True, default=-0.45, kw_only=True)

    name: ClassVar[str] = "hopper"
    model: ClassVar[Callable[[], Tree]] = staticmethod(hopper_chain)
    ends_early: ClassVar[bool] = True

    def reward(self, state: TaskState, action: Float[ArrayLike, " 3"], next_state: TaskState) -> Float[Array, ""]:
        """DFlex's hopper reward of the state the step lands in (see the table)."""
        q, qd = next_state.q, next_state.qd
        h = jnp.clip(q[1] - (self.termination_height + 0.15), -1.0, 0.3)
        height = jnp.where(h < 0.0, -200.0 * h * h, h)
        upright = 1.0 - (q[2] / (math.pi / 6)) ** 2
        return qd[0] + height + upright - self._action_cost(action)

    def terminated(self, state: TaskState) -> Bool[Array, ""]:
        """The hopper fell: its root below ``termination_height``.

        Args:
            state: one state.
        """
        return state.q[1] < self.termination_height


@final
class Cheetah(AbstractPlanarLocomotion):
    """DFlex's half-cheetah (the SHAC paper's); build it with :meth:`diffrl`.

    =====================  =============================================================================================
    state ``q`` / ``qd``   (x, z, pitch, bthigh, bshin, bfoot, fthigh, fshin, ffoot): ``z`` the root's height above
                           1 m (the torso at 1 + z m); and their rates
    action (gear)          six joint torques ``200 a`` N m, ``a`` clipped to [-1, 1]
    observation (17)       ``(q[1:], qd)``, unclipped
    reward per step        ``qd[0] - 0.1 |a|^2`` of the state the step lands in
    early end              none
    episode                1000 control steps of 1/60 s
    reset                  ``q`` = (0, -0.2, 0, ...) + U(-0.1, 0.1) on every coordinate, ``qd`` = U(-0.25, 0.25); the
                           torso 0.8 m up, the lowest foot 0.18 m above the ground: it drops
    bodies (kg)            torso and head 9.457, bthigh 2.336, bshin 2.402, bfoot 1.657, fthigh 2.176, fshin 1.817,
                           ffoot 1.338 (21.18); ffoot rests outside its range [-3.1, -0.3] at 0 (the spring and the
                           limit settle near -0.28)
    success                the torso never upside down (``|pitch| < pi/2`` throughout): a run, not a flip
    =====================  =============================================================================================
    """

    chain: Tree
    dt: float = eqx.field(static=True, default=1.0 / 60.0, kw_only=True)
    horizon: int = eqx.field(static=True, default=1000, kw_only=True)
    substeps: int = eqx.field(static=True, default=16, kw_only=True)
    solver: TaskSolver = eqx.field(static=True, default=DFLEX_SOLVER, kw_only=True)
    start: tuple[float, ...] = eqx.field(static=True, default=(0.0, -0.2) + (0.0,) * 7, kw_only=True)
    noise_q: float = eqx.field(static=True, default=0.1, kw_only=True)
    noise_qd: float = eqx.field(static=True, default=0.25, kw_only=True)
    action_cost: float = eqx.field(static=True, default=0.1, kw_only=True)

    name: ClassVar[str] = "cheetah"
    model: ClassVar[Callable[[], Tree]] = staticmethod(cheetah_chain)

    def reward(self, state: TaskState, action: Float[ArrayLike, " 6"], next_state: TaskState) -> Float[Array, ""]:
        """``qd[0] - 0.1 |a|^2`` of the state the step lands in."""
        return next_state.qd[0] - self._action_cost(action)

    def succeeded(self, q: Float[ArrayLike, "*batch T n"]) -> Bool[Array, " *batch"]:
        """The torso never upside down: ``|pitch| < pi/2`` at every step.

        Args:
            q: a trajectory of coordinates, shape ``(*batch, T, n)``.
        """
        return jnp.all(jnp.abs(jnp.asarray(q)[..., 2]) < math.pi / 2, axis=-1)
