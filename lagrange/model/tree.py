"""Spatial kinematic trees: rigid bodies in 3-D joined by hinges, slides, balls and free joints (MuJoCo's model).

A :class:`Tree` is a list of :class:`Body`, parents first, each placed in its parent's frame by ``pos`` and ``quat``
and moved by its joints (:mod:`lagrange.model.joints`), and :class:`Motor` s that drive hinges and slides. Its
coordinates ``q`` (``nq`` of them) and velocities ``qd`` (``nv``) are MuJoCo's ``qpos`` and ``qvel``: joint by joint,
in the order of the bodies and of each body's joints. A body without joints is welded to its parent. Structure is
static (parents, joint kinds, axes, which joints are driven); physical parameters are arrays, so ``jax.grad`` with
respect to masses, inertias, positions, damping or gears works; a parameter given as exactly zero (a centre of mass at
the origin, a principal inertia, an anchor at the body's origin) leaves its terms out of the compiled program when the
tree is a constant of the traced function.

Frames: the world's z is up by default (``gravity = (0, 0, -9.81)``); a body's frame is ``R_parent quat`` turned and
``p_parent + R_parent pos`` placed, then moved by its joints in order (the docs' conventions page).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.model.checks import check_array, check_points, is_zero, traced
from lagrange.model.contact import PenaltyContact
from lagrange.model.joints import AbstractJoint, Free, Hinge, Slide
from lagrange.model.limits import PenaltyLimits
from lagrange.model.muscles import Muscle
from lagrange.model.plane import normal

__all__ = ["AffineActuator", "Body", "Motor", "Tree", "WORLD"]

WORLD = -1
"""The ``parent`` of a body that hangs from the world."""


class Body(eqx.Module):
    """A rigid body, its place on its parent and the joints that move it.

    Args:
        mass: [kg], >= 0.
        inertia: the rotational inertia about the centre of mass in the body's frame [kg m^2]: the three principal
            moments along the body's axes, or a symmetric positive semi-definite 3x3.
        com: the centre of mass in the body's frame [m] (MuJoCo's ``ipos``).
        joints: the joints that move the body against its parent, in order (none: welded to it).
        parent: the index of a body listed before it, or :data:`WORLD`; ``None`` (the default) is the body listed
            just before it (the world for the first); static.
        pos: the body frame's origin in the parent's frame as written [m].
        quat: the body frame's orientation in the parent's frame as written, a quaternion ``(w, x, y, z)``
            (normalised here); static, as the joints' axes are.
        contacts: ground contact points ``(x, y, z, radius)`` in the body's frame [m] (a capsule's two end points,
            a sphere's centre, a box's corners with radius 0); static. The tree's ``contact`` law presses them.
        tip: the body's far end in its frame [m], or ``None``: where a drawing of the body ends (a planar link's
            ``length`` along its direction, :func:`lagrange.kinematics.tip_positions`); no force acts there.
        name: a name for messages; static.
    """

    mass: Float[Array, ""]
    inertia: Float[Array, "3 3"]
    com: Float[Array, "3"]
    pos: Float[Array, "3"]
    joints: tuple[AbstractJoint, ...]
    tip: Float[Array, "3"] | None
    quat: tuple[float, float, float, float] = eqx.field(static=True)
    parent: int | None = eqx.field(static=True)
    contacts: tuple[tuple[float, float, float, float], ...] = eqx.field(static=True)
    name: str | None = eqx.field(static=True)

    def __init__(self, mass: Float[ArrayLike, ""], inertia: Float[ArrayLike, "3"] | Float[ArrayLike, "3 3"] = (0, 0, 0),
                 com: Float[ArrayLike, "3"] = (0.0, 0.0, 0.0), *, joints: Sequence[AbstractJoint] = (),
                 parent: int | None = None, pos: Float[ArrayLike, "3"] = (0.0, 0.0, 0.0),
                 quat: Float[ArrayLike, "4"] = (1.0, 0.0, 0.0, 0.0), contacts=(),
                 tip: Float[ArrayLike, "3"] | None = None, name: str | None = None):
        who = f"Body {name!r}" if name else "Body"
        self.mass = check_array(f"{who}.mass", mass, nonnegative=True)
        if np.shape(inertia) == (3,):  # principal moments along the body's axes
            inertia = jnp.diag(inertia) if traced(inertia) else np.diag(np.asarray(inertia, float))
        self.inertia = check_array(f"{who}.inertia", inertia, (3, 3))
        J = np.asarray(self.inertia) if not traced(self.inertia) else None
        if J is not None:
            if np.max(np.abs(J - J.T)) > 1e-12 * max(1.0, np.max(np.abs(J))):
                raise ValueError(f"{who}.inertia must be symmetric, got {J.tolist()}")
            if np.min(np.linalg.eigvalsh(J)) < -1e-12 * max(1.0, np.max(np.abs(J))):
                raise ValueError(f"{who}.inertia must be positive semi-definite, got eigenvalues "
                                 f"{np.linalg.eigvalsh(J).tolist()}")
        self.com = check_array(f"{who}.com", com, (3,))
        self.pos = check_array(f"{who}.pos", pos, (3,))
        if traced(quat):
            raise TypeError(f"{who}.quat is static (a body's orientation is structure, as a joint's axis is): give "
                            "four numbers, not a traced value")
        quat = np.asarray(check_array(f"{who}.quat", quat, (4,)), float)  # NumPy: static
        norm = float(np.linalg.norm(quat))
        if norm < 1e-12:
            raise ValueError(f"{who}.quat must be a non-zero quaternion (w, x, y, z), got {quat.tolist()}")
        if abs(norm - 1.0) > 4 * np.finfo(float).eps:  # a unit quaternion's round-off is kept as given
            quat = quat / norm
        self.quat = tuple(float(x) for x in quat)
        self.tip = None if tip is None else check_array(f"{who}.tip", tip, (3,))
        joints = tuple(joints) if not isinstance(joints, AbstractJoint) else (joints,)
        for k, j in enumerate(joints):
            if not isinstance(j, AbstractJoint):
                raise TypeError(f"{who}.joints[{k}] must be a joint of lagrange.joints (Hinge, Slide, Ball, Free), "
                                f"got {type(j).__name__}")
            if isinstance(j, Free) and k != 0:
                raise ValueError(f"{who}.joints[{k}] is a Free joint: a free joint must be a body's only joint")
        if any(isinstance(j, Free) for j in joints) and len(joints) > 1:
            raise ValueError(f"{who}: a Free joint must be the body's only joint, got {len(joints)} joints")
        self.joints = joints
        if parent is not None and (isinstance(parent, bool) or not isinstance(parent, (int, np.integer))
                                   or parent < WORLD):
            raise ValueError(f"{who}.parent must be None, -1 (the world) or the index of a body listed before it, "
                             f"got {parent!r}")
        self.parent = None if parent is None else int(parent)
        self.contacts = check_points("contacts", contacts, owner=who, coords=("x", "y", "z"))
        self.name = name


class Motor(eqx.Module):
    """A motor on a hinge or slide: generalized force ``gear * u`` on it, ``u`` first clamped into
    ``control_range`` where one is given (MuJoCo's ``<motor>`` with ``ctrlrange``).

    Args:
        joint: the joint's index in the tree's order (bodies in order, each body's joints in order); static.
        gear: [N m or N per unit of control], > 0.
        control_range: ``(lo, hi)`` or ``None``; static.
    """

    gear: Float[Array, ""]
    joint: int = eqx.field(static=True)
    control_range: tuple[float, float] | None = eqx.field(static=True)

    def __init__(self, joint: int, gear: Float[ArrayLike, ""] = 1.0, control_range=None):
        if isinstance(joint, bool) or not isinstance(joint, (int, np.integer)) or joint < 0:
            raise ValueError(f"Motor.joint must be a joint's index >= 0, got {joint!r}")
        self.joint = int(joint)
        self.gear = check_array("Motor.gear", gear, nonnegative=True)
        if not traced(self.gear) and float(np.asarray(self.gear)) <= 0:
            raise ValueError(f"Motor.gear must be > 0 (reverse a motor by negating its control), got "
                             f"{float(np.asarray(self.gear))}")
        if control_range is not None:
            lo, hi = (float(x) for x in control_range)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"Motor.control_range must be finite with lo < hi, got {control_range!r}")
            control_range = (lo, hi)
        self.control_range = control_range

    state_dependent: ClassVar[bool] = False
    """Whether the force depends on the joint's position or velocity (then only the general algorithms add it)."""

    def force(self, u, length, velocity):
        """The actuator's force before ``gear``: the clamped control ``u`` itself."""
        return u


class AffineActuator(Motor):
    """An actuator whose force is affine in its control, its length and its velocity (MuJoCo's ``<general>`` with
    ``gaintype="fixed"`` and ``biastype="affine"``; ``<position>`` and ``<velocity>`` are such actuators).

    On joint ``j`` with ``length = gear * q_j`` and ``velocity = gear * qd_j``, the actuator's force is
    ``f = gain * u + bias[0] + bias[1] * length + bias[2] * velocity``, ``u`` first clamped into ``control_range`` and
    ``f`` then into ``force_range`` where given, and its generalized force ``gear * f`` (MuJoCo's ``qfrc_actuator``).
    A plain :class:`Motor` is the one with ``gain = 1`` and no bias. The general rigid-body algorithms add these
    forces; a planar tree with one runs on them (:func:`lagrange.dynamics.backend`).

    Args:
        joint, gear, control_range: as for :class:`Motor`.
        gain: MuJoCo's ``gainprm[0]``.
        bias: ``(b0, b1, b2)``, MuJoCo's ``biasprm[:3]``.
        force_range: ``(lo, hi)`` or ``None`` (MuJoCo's ``forcerange`` where ``forcelimited``); static.
    """

    gain: Float[Array, ""]
    bias: Float[Array, "3"]
    force_range: tuple[float, float] | None = eqx.field(static=True)
    state_dependent: ClassVar[bool] = True

    def __init__(self, joint: int, gear: Float[ArrayLike, ""] = 1.0, control_range=None, *,
                 gain: Float[ArrayLike, ""] = 1.0, bias: Float[ArrayLike, "3"] = (0.0, 0.0, 0.0), force_range=None):
        super().__init__(joint, gear, control_range)
        self.gain = check_array("AffineActuator.gain", gain)
        self.bias = check_array("AffineActuator.bias", bias, (3,))
        if force_range is not None:
            lo, hi = (float(x) for x in force_range)
            if not (lo < hi) or np.isnan(lo) or np.isnan(hi):
                raise ValueError(f"AffineActuator.force_range must have lo < hi, got {force_range!r}")
            force_range = (lo, hi)
        self.force_range = force_range

    @classmethod
    def position(cls, joint: int, kp: float, kv: float = 0.0, **kw) -> AffineActuator:
        """MuJoCo's ``<position kp kv>``: ``f = kp (u - length) - kv velocity``, ``u`` the target position."""
        return cls(joint, gain=kp, bias=(0.0, -kp, -kv), **kw)

    @classmethod
    def velocity(cls, joint: int, kv: float, **kw) -> AffineActuator:
        """MuJoCo's ``<velocity kv>``: ``f = kv (u - velocity)``, ``u`` the target velocity."""
        return cls(joint, gain=kv, bias=(0.0, 0.0, -kv), **kw)

    def force(self, u, length, velocity):
        """The actuator's force ``f`` (before ``gear``) at the clamped control ``u``, ``(...)``."""
        f = self.gain * u + self.bias[0] + self.bias[1] * length + self.bias[2] * velocity
        if self.force_range is not None:
            f = jnp.clip(f, *(jnp.asarray(x, f.dtype) for x in self.force_range))
        return f


class Tree(eqx.Module):
    """An immutable spatial kinematic tree (a forest: several bodies may hang from the world).

    Args:
        bodies: :class:`Body` s, parents before children.
        gravity: the gravitational acceleration vector [m/s^2] in the world frame (MuJoCo's ``opt.gravity``); a
            component given as exactly 0 (a number, or an entry of a concrete vector) is structurally absent, as every
            zero term: it stays 0 where the tree's parameters are traced (:attr:`gravity_support`).
        motors: the :class:`Motor` s, in the order of the controls ``u``.
        muscles: the :class:`lagrange.Muscle` s, their activations the controls after the motors', in order.
        contact: the ground contact law (:class:`lagrange.PenaltyContact`; its ``ground`` the height of the level
            plane ``z = ground``) pressing the bodies' ``contacts``; given exactly when some body has contact points.
        limits: the joint limit law (:class:`lagrange.PenaltyLimits`) for the hinges and slides with a ``range``;
            given exactly when some joint has one.

    Attributes:
        nq, nv, m: the numbers of coordinates, velocities and controls (the motors' and the muscles').
        parents: each body's parent (:data:`WORLD` for a body of the world); static.
        joint_body: the body of each joint; static.
        qadr, vadr: where each joint's coordinates start in ``q`` and its velocities in ``qd``; static.
        gravity_support: which of gravity's three components were not given as exactly 0; static. The planar backend
            reads it where gravity is traced, to know that the part of gravity it cannot carry (across the plane's
            ``z``) is absent.

    Raises:
        TypeError, ValueError: naming the field, for a body that is not one, a parent that is not listed before
            its child, a motor on a joint that does not exist or is not a hinge or slide, two motors on one joint,
            a free joint on a body that does not hang from the world, a muscle's waypoint on a body that does not
            exist.
    """

    bodies: tuple[Body, ...]
    gravity: Float[Array, "3"]
    motors: tuple[Motor, ...]
    muscles: tuple[Muscle, ...]
    contact: PenaltyContact | None
    limits: PenaltyLimits | None
    parents: tuple[int, ...] = eqx.field(static=True)
    joint_body: tuple[int, ...] = eqx.field(static=True)
    qadr: tuple[int, ...] = eqx.field(static=True)
    vadr: tuple[int, ...] = eqx.field(static=True)
    gravity_support: tuple[bool, bool, bool] = eqx.field(static=True)

    def __init__(self, bodies: Sequence[Body], gravity: Float[ArrayLike, "3"] = (0.0, 0.0, -9.81), *,
                 motors: Sequence[Motor] = (), muscles: Sequence[Muscle] = (),
                 contact: PenaltyContact | None = None, limits: PenaltyLimits | None = None):
        bodies = (bodies,) if isinstance(bodies, Body) else tuple(bodies)
        if not bodies:
            raise ValueError("Tree.bodies must hold at least one Body")
        parents = []
        for i, b in enumerate(bodies):
            if not isinstance(b, Body):
                raise TypeError(f"Tree.bodies[{i}] must be a lagrange.model.tree.Body, got {type(b).__name__}")
            p = i - 1 if b.parent is None else b.parent
            if p >= i:
                raise ValueError(f"Tree.bodies[{i}].parent must be -1 (the world) or the index of a body listed "
                                 f"before it (0..{i - 1}), got {p}")
            if p != WORLD and any(isinstance(j, Free) for j in b.joints):
                raise ValueError(f"Tree.bodies[{i}] has a Free joint but hangs from body {p}: a free body must hang "
                                 "from the world")
            parents.append(p)
        self.bodies = bodies
        self.parents = tuple(parents)
        support = None
        if isinstance(gravity, (tuple, list)) and len(gravity) == 3 and traced(*gravity):  # some entries known
            support = tuple(not is_zero(x) for x in gravity)
            gravity = jnp.stack([jnp.asarray(x, jax.dtypes.canonicalize_dtype(float)) for x in gravity])
        self.gravity = check_array("Tree.gravity", gravity, (3,))
        if support is None:
            support = (True,) * 3 if traced(self.gravity) else tuple(bool(x != 0) for x in self.gravity)
        self.gravity_support = support
        joint_body, qadr, vadr, nq, nv = [], [], [], 0, 0
        for i, b in enumerate(bodies):
            for j in b.joints:
                joint_body.append(i)
                qadr.append(nq)
                vadr.append(nv)
                nq, nv = nq + j.nq, nv + j.nv
        if nv == 0:
            raise ValueError("Tree: the bodies have no joint; a tree needs at least one")
        self.joint_body, self.qadr, self.vadr = tuple(joint_body), tuple(qadr), tuple(vadr)
        motors = tuple(motors)
        seen = set()
        for k, mo in enumerate(motors):
            if not isinstance(mo, Motor):
                raise TypeError(f"Tree.motors[{k}] must be a lagrange.model.tree.Motor, got {type(mo).__name__}")
            if mo.joint >= len(joint_body):
                raise ValueError(f"Tree.motors[{k}].joint is {mo.joint}; the tree has joints 0..{len(joint_body) - 1}")
            if not isinstance(self.joints[mo.joint], (Hinge, Slide)):
                raise ValueError(f"Tree.motors[{k}] drives joint {mo.joint}, a {type(self.joints[mo.joint]).__name__}:"
                                 " a motor drives a Hinge or a Slide")
            if mo.joint in seen:
                raise ValueError(f"Tree.motors[{k}]: joint {mo.joint} already has a motor")
            seen.add(mo.joint)
        self.motors = motors
        muscles = tuple(muscles)
        for k, mu in enumerate(muscles):
            if not isinstance(mu, Muscle):
                raise TypeError(f"Tree.muscles[{k}] must be a lagrange.Muscle, got {type(mu).__name__}")
            bad = [b for b in mu.bodies if b >= len(bodies)]
            if bad:
                raise ValueError(f"Tree.muscles[{k}]{f' ({mu.name!r})' if mu.name else ''} has a waypoint on body "
                                 f"{bad[0]}; the tree has bodies 0..{len(bodies) - 1}")
        self.muscles = muscles
        touching = [i for i, b in enumerate(bodies) if b.contacts]
        limited = [k for k, j in enumerate(self.joints) if j.range is not None]
        if contact is not None and not isinstance(contact, PenaltyContact):
            raise TypeError(f"Tree.contact must be a lagrange.PenaltyContact or None, got {type(contact).__name__}")
        if limits is not None and not isinstance(limits, PenaltyLimits):
            raise TypeError(f"Tree.limits must be a lagrange.PenaltyLimits or None, got {type(limits).__name__}")
        if (contact is None) != (not touching):
            raise ValueError(f"Tree: bodies {touching} have contact points but the tree has no contact law: pass "
                             "Tree(..., contact=lagrange.PenaltyContact(ke, kd, kf, mu)), or drop the points"
                             if contact is None else "Tree.contact is given but no body has contact points: give "
                             "bodies Body(..., contacts=[(x, y, z, radius), ...]), or drop contact")
        if (limits is None) != (not limited):
            raise ValueError(f"Tree: joints {limited} have a range but the tree has no limit law: pass "
                             "Tree(..., limits=lagrange.PenaltyLimits(ke, kd)), or drop the ranges"
                             if limits is None else "Tree.limits is given but no joint has a range: give hinges or "
                             "slides Hinge(..., range=(lower, upper)), or drop limits")
        if limits is not None:
            limits.check_count(len(limited))
        self.contact, self.limits = contact, limits

    @property
    def joints(self) -> tuple[AbstractJoint, ...]:
        """Every joint, in the order of ``q``."""
        return tuple(j for b in self.bodies for j in b.joints)

    @property
    def nq(self) -> int:
        """Number of coordinates."""
        return sum(j.nq for j in self.joints)

    @property
    def nv(self) -> int:
        """Number of velocities (degrees of freedom)."""
        return sum(j.nv for j in self.joints)

    @property
    def n(self) -> int:
        """Deprecated: :attr:`nv` (a chain's number of links, when chains were a model of their own)."""
        warnings.warn("Tree.n is deprecated: use Tree.nv (velocities, the size of M) or Tree.nq (coordinates)",
                      DeprecationWarning, stacklevel=2)
        return self.nv

    @property
    def planar(self) -> bool:
        """Whether the tree moves in one plane (:func:`lagrange.model.plane.normal`): every joint a hinge or a slide,
        the hinges about one common axis, the slides across it; static. The dynamics of a planar tree are derived by
        the planar backend (:mod:`lagrange.planar`), the others' by the general rigid-body algorithms
        (:mod:`lagrange.rbda`)."""
        return normal(self) is not None

    @property
    def mass(self) -> Float[Array, " bodies"]:
        """Every body's mass [kg], in order (its dtype is the tree's)."""
        return jnp.stack([jnp.asarray(b.mass) for b in self.bodies])

    @property
    def m(self) -> int:
        """Number of controls: the motors', then the muscles' activations."""
        return len(self.motors) + len(self.muscles)

    @property
    def actuated(self) -> tuple[int, ...]:
        """The velocity index each control drives; static."""
        return tuple(self.vadr[mo.joint] for mo in self.motors)

    @property
    def gear(self) -> Float[Array, " m"] | None:
        """The motors' gears, in the order of the controls; ``None`` without motors."""
        return jnp.stack([jnp.asarray(mo.gear) for mo in self.motors]) if self.motors else None

    @property
    def control_ranges(self) -> tuple[tuple[float, float] | None, ...] | None:
        """Each motor's ``(lo, hi)`` or ``None``; ``None`` when no control is clamped; static."""
        ranges = tuple(mo.control_range for mo in self.motors)
        return ranges if any(r is not None for r in ranges) else None

    def neutral(self) -> Float[Array, " nq"]:
        """The coordinates at which every body sits as written (hinges and slides at ``ref``, identity quaternions,
        free bodies at their ``pos`` and ``quat``): MuJoCo's ``qpos0``."""
        out = []
        for b in self.bodies:
            for j in b.joints:
                if isinstance(j, Free):
                    out.append(np.concatenate([np.asarray(b.pos, float), np.asarray(b.quat, float)]))
                else:
                    out.append(j.neutral())
        return jnp.asarray(np.concatenate(out))

    def joint_index(self, name: str) -> int:
        """The index in :attr:`joints` of the joint named ``name`` (its coordinates start at ``qadr[k]``, its
        velocities at ``vadr[k]``).

        Raises:
            KeyError: naming the tree's joint names, where none is ``name``.
        """
        return _index("joint", [j.name for j in self.joints], name)

    def muscle_index(self, name: str) -> int:
        """The index in :attr:`muscles` of the muscle named ``name`` (its activation is control ``len(motors) + k``).

        Raises:
            KeyError: naming the tree's muscle names, where none is ``name``.
        """
        return _index("muscle", [mu.name for mu in self.muscles], name)

    def body_index(self, name: str) -> int:
        """The index in :attr:`bodies` of the body named ``name``.

        Raises:
            KeyError: naming the tree's body names, where none is ``name``.
        """
        return _index("body", [b.name for b in self.bodies], name)

    def subtree(self, i: int) -> tuple[int, ...]:
        """Body ``i`` and every body below it, in order; static."""
        out = [i]
        for k in range(i + 1, len(self.bodies)):
            if self.parents[k] in out:
                out.append(k)
        return tuple(out)


def _index(kind: str, names: list, name: str) -> int:
    """The position of ``name`` among the tree's ``names`` of ``kind`` (``"joint"``, ``"body"``)."""
    if name not in names:
        plural = "bodies" if kind == "body" else f"{kind}s"
        raise KeyError(f"the tree has no {kind} named {name!r}; its {plural}: {[n for n in names if n]}")
    return names.index(name)


def check_tree(model, name: str = "the model") -> None:
    """Raise a TypeError naming ``name`` unless ``model`` is a :class:`Tree` (a :class:`lagrange.chain.Chain` is
    one): what every function taking a model checks first."""
    if not isinstance(model, Tree):
        raise TypeError(f"{name} must be a lagrange.Tree (a lagrange.chain.Chain is one), got {type(model).__name__}")
