"""Joints of a spatial tree: hinge and slide about any axis, ball, and free, in MuJoCo's conventions.

Each joint knows its number of coordinates ``nq`` and of velocities ``nv``, how it moves its body's frame
(:meth:`AbstractJoint.local`), its motion subspace (the columns ``S`` that map its velocities to the body's spatial
velocity) and how to step its coordinates (:meth:`AbstractJoint.integrate`). The conventions are MuJoCo's, so that a
tree read from MJCF has ``q = qpos`` and ``qd = qvel``:

==========  ===  ===  ==============================================  ============================================
joint       nq   nv   q                                               qd
==========  ===  ===  ==============================================  ============================================
``Hinge``   1    1    angle about ``axis`` [rad] (``ref`` at the      angular speed [rad/s]
                      body's frame as written)
``Slide``   1    1    displacement along ``axis`` [m] (``ref`` as      speed [m/s]
                      for the hinge)
``Ball``    4    3    unit quaternion ``(w, x, y, z)`` of the body    angular velocity in the body's frame [rad/s]
                      against its frame as written
``Free``    7    6    position [m] of the body's origin in the world   linear velocity of the origin in the world
                      and unit quaternion of its orientation           frame [m/s], angular velocity in the body's
                                                                      frame [rad/s]
==========  ===  ===  ==============================================  ============================================

The axis and the anchor ``pos`` of a hinge, slide or ball are in the body's frame; a body's joints act in the order
given, each in the frame the joints before it left (MuJoCo's ``mj_kinematics``). A quaternion is normalised wherever
it is read, as MuJoCo does, and the integration keeps it unit (:func:`lagrange.rbda.integrate_positions`).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from lagrange.math.sincos import sincos
from lagrange.model.checks import check_array, check_pair
from lagrange.math import spatial as al

__all__ = ["AbstractJoint", "Ball", "DFlexBall", "Free", "Hinge", "Slide", "JOINTS"]


def _axis(name: str, axis) -> tuple[float, float, float]:
    try:
        a = np.asarray(axis, float).reshape(-1)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{name}.axis must be three numbers, got {axis!r}") from err
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}.axis must be three finite numbers, got {axis!r}")
    norm = float(np.linalg.norm(a))
    if norm < 1e-12:
        raise ValueError(f"{name}.axis must not be zero (a direction: any non-zero length, normalised), got {axis!r}")
    if abs(norm - 1.0) > 4 * np.finfo(float).eps:  # a unit axis's round-off is kept as given
        a = a / norm
    return tuple(0.0 if abs(x) < 1e-15 else float(x) for x in a)


def _name(kind: str, name):
    if name is not None and (not isinstance(name, str) or not name):
        raise TypeError(f"{kind}.name must be a non-empty string or None, got {name!r}")
    return name


class AbstractJoint(eqx.Module):
    """A joint: ``nq`` coordinates, ``nv`` velocities, and per velocity its ``damping`` [N s/m or N m s/rad]
    (generalized force ``-damping qd``), ``armature`` [kg or kg m^2] (added to ``M``'s diagonal) and a spring of
    ``stiffness`` toward the coordinates ``springref`` (a ball's and a free joint's: its rotation by the rotation
    vector from ``springref``'s quaternion, as MuJoCo's ``qfrc_spring``)."""

    nq: ClassVar[int]
    nv: ClassVar[int]
    damping: Float[ArrayLike, ""]
    armature: Float[ArrayLike, ""]
    stiffness: Float[ArrayLike, ""]

    # a free joint places its body in the world itself: the placement of the body as written does not apply
    places_body: ClassVar[bool] = False

    @classmethod
    def local(cls, joints, q):
        """How joints of this kind move their frames, several at once: the rotation and the origin of each frame after
        its joint in the frame before it (``x_before = R_J x_after + p_J``).

        Args:
            joints: the joints (instances of this class), ``n`` of them.
            q: their coordinates, ``(..., n, nq)``.

        Returns:
            ``(R_J, p_J)``, shapes ``(..., n, 3, 3)`` and ``(..., n, 3)``.
        """
        raise NotImplementedError

    @classmethod
    def subspace(cls, joints, R, p):
        """The motion subspaces of joints of this kind, several at once, from the frames after them.

        Args:
            joints: the joints (instances of this class), ``n`` of them.
            R: the frames' rotations after the joints (world from body), ``(..., n, 3, 3)``.
            p: their origins, relative to the tree's reference point [m], ``(..., n, 3)``.

        Returns:
            ``S (..., n, nv, 6)``: per velocity, the body's spatial velocity ``(w, v)`` per unit of it, in world-aligned
            coordinates at the reference point.
        """
        raise NotImplementedError

    def integrate(self, q, v, h):
        """The coordinates ``q`` (arrays ``(..., nq)``) moved by the velocities ``v`` (``(..., nv)``) for ``h``
        seconds: ``q + h v`` for a hinge or slide, the quaternion turned by the exponential map and kept unit."""
        raise NotImplementedError

    def spring(self, q, ref):
        """The displacement ``(..., nv)`` the spring pulls back from the rest coordinates ``ref`` (``(nq,)``):
        ``q - ref``, or the rotation vector from ``ref``'s quaternion to ``q``'s."""
        raise NotImplementedError

    def spring_energy(self, q, ref):
        """Twice the spring's potential per unit of stiffness, ``(...)``: ``|spring(q, ref)|^2`` (the potential is
        ``1/2 stiffness`` times it)."""
        d = self.spring(q, ref)
        return jnp.sum(d * d, axis=-1)

    def neutral(self):
        """The coordinates of the body's frame as written (``ref``; the identity quaternion), a NumPy ``(nq,)``."""
        raise NotImplementedError


class _AxisJoint(AbstractJoint):
    """A hinge or a slide: one coordinate along a static unit ``axis``."""

    nq: ClassVar[int] = 1
    nv: ClassVar[int] = 1
    axis: tuple[float, float, float] = eqx.field(static=True)
    damping: Float[ArrayLike, ""]
    armature: Float[ArrayLike, ""]
    stiffness: Float[ArrayLike, ""]
    springref: Float[ArrayLike, ""]
    range: tuple[float, float] | None = eqx.field(static=True)
    ref: float = eqx.field(static=True)
    pos: tuple[float, float, float] = eqx.field(static=True)
    name: str | None = eqx.field(static=True)

    def __init__(self, axis=(0.0, 0.0, 1.0), pos=(0.0, 0.0, 0.0), *, ref=0.0, damping=0.0, armature=0.0,
                 stiffness=0.0, springref=None, range=None, name: str | None = None):
        self.name = _name(type(self).__name__, name)
        name = type(self).__name__
        self.range = check_pair("range", range, owner=name)
        self.axis = _axis(name, axis)
        self.pos = _static_point(f"{name}.pos", pos)
        if isinstance(ref, jax.core.Tracer):
            raise TypeError(f"{name}.ref is static (it sets the coordinate's zero): give a number, not a traced value")
        self.ref = float(check_array(f"{name}.ref", ref))
        self.damping = check_array(f"{name}.damping", damping, nonnegative=True)
        self.armature = check_array(f"{name}.armature", armature, nonnegative=True)
        self.stiffness = check_array(f"{name}.stiffness", stiffness, nonnegative=True)
        self.springref = check_array(f"{name}.springref", self.ref if springref is None else springref)

    def integrate(self, q, v, h):
        return q + h * v

    def spring(self, q, ref):
        return q - ref

    def neutral(self):
        return np.array([float(np.asarray(self.ref))])


class Hinge(_AxisJoint):
    """A hinge: the body turns by ``q - ref`` about ``axis`` (unit after normalising; static) through the anchor
    ``pos`` [m], both in the body's frame (MuJoCo's ``<joint type="hinge">``).

    Args:
        axis: the rotation axis (3 numbers, any non-zero length); static.
        pos: the anchor [m], three numbers; static (the joint's place, as its axis).
        ref: the angle at which the body sits as written [rad] (MuJoCo's ``ref``); static.
        damping, armature, stiffness: see :class:`AbstractJoint`.
        springref: the spring's rest angle [rad] (default ``ref``).
        range: ``(lower, upper)`` [rad], pressed by the tree's ``limits`` law, or ``None``; static.
        name: the joint's name (MJCF's and URDF's), by which :meth:`lagrange.Tree.joint_index` finds it; static.
    """

    @classmethod
    def local(cls, joints, q):
        axis, pos, ref = _stacked(joints, q.dtype)
        sn, c = sincos(q[..., 0] - ref)
        R = al.axis_rotation(axis, c, sn)
        return R, pos - al.matvec(R, pos)  # turned about the anchor

    @classmethod
    def subspace(cls, joints, R, p):
        axis, pos, _ = _stacked(joints, R.dtype)
        a, anchor = al.matvec(R, axis), p + al.matvec(R, pos)  # the axis and the anchor do not move with the turn
        return jnp.concatenate([a, al.cross(anchor, a)], axis=-1)[..., None, :]


class Slide(_AxisJoint):
    """A slide: the body moves by ``q - ref`` along ``axis`` (unit after normalising; static), in the body's frame
    (MuJoCo's ``<joint type="slide">``; ``pos`` does not move it).

    Args:
        axis: the direction (3 numbers, any non-zero length); static.
        pos: unused by the motion (kept for MJCF's round trip) [m], three numbers; static.
        ref: the displacement at which the body sits as written [m]; static.
        damping, armature, stiffness: see :class:`AbstractJoint`.
        springref: the spring's rest displacement [m] (default ``ref``).
        range: ``(lower, upper)`` [m], pressed by the tree's ``limits`` law, or ``None``; static.
        name: the joint's name (MJCF's and URDF's), by which :meth:`lagrange.Tree.joint_index` finds it; static.
    """

    @classmethod
    def local(cls, joints, q):
        axis, _, ref = _stacked(joints, q.dtype)
        R = jnp.broadcast_to(al.eye3(q.dtype), q.shape[:-1] + (3, 3))
        return R, (q[..., 0] - ref)[..., None] * axis

    @classmethod
    def subspace(cls, joints, R, p):
        axis, _, _ = _stacked(joints, R.dtype)
        a = al.matvec(R, axis)
        return jnp.concatenate([jnp.zeros_like(a), a], axis=-1)[..., None, :]


class Ball(AbstractJoint):
    """A ball joint: the body turns by the unit quaternion ``q`` about the anchor ``pos`` [m] in its frame; its
    velocities are the angular velocity in the body's frame (MuJoCo's ``<joint type="ball">``).

    Args:
        pos: the anchor [m], three numbers; static.
        damping, armature, stiffness: see :class:`AbstractJoint`, the same for each of the three velocities.
        springref: the spring's rest quaternion, shape ``(4,)`` (default the identity).
        name: the joint's name (MJCF's and URDF's), by which :meth:`lagrange.Tree.joint_index` finds it; static.
    """

    nq: ClassVar[int] = 4
    nv: ClassVar[int] = 3
    range: ClassVar[None] = None  # no limit on a ball (MJCF's ball-joint ranges are refused by name)
    damping: Float[ArrayLike, ""]
    armature: Float[ArrayLike, ""]
    stiffness: Float[ArrayLike, ""]
    springref: Float[ArrayLike, "4"]
    pos: tuple[float, float, float] = eqx.field(static=True)
    name: str | None = eqx.field(static=True)

    def __init__(self, pos=(0.0, 0.0, 0.0), *, damping=0.0, armature=0.0, stiffness=0.0,
                 springref=(1.0, 0.0, 0.0, 0.0), name: str | None = None):
        self.name = _name("Ball", name)
        self.pos = _static_point("Ball.pos", pos)
        self.damping = check_array("Ball.damping", damping, nonnegative=True)
        self.armature = check_array("Ball.armature", armature, nonnegative=True)
        self.stiffness = check_array("Ball.stiffness", stiffness, nonnegative=True)
        self.springref = check_array("Ball.springref", springref, (4,))

    @classmethod
    def local(cls, joints, q):
        pos = _stack([j.pos for j in joints], q.dtype)
        R = al.quat_to_matrix(al.normalize_quat(q))
        return R, pos - al.matvec(R, pos)

    @classmethod
    def subspace(cls, joints, R, p):
        anchor = p + al.matvec(R, _stack([j.pos for j in joints], R.dtype))
        axes = jnp.swapaxes(R, -1, -2)  # the body's axes in the world, one per row
        return jnp.concatenate([axes, al.cross(anchor[..., None, :], axes)], axis=-1)

    def integrate(self, q, v, h):
        return al.quat_integrate(q, v, h)

    def spring(self, q, ref):
        return al.quat_difference(al.normalize_quat(q), al.normalize_quat(jnp.asarray(ref, q.dtype)))

    def neutral(self):
        return np.array([1.0, 0.0, 0.0, 0.0])


class DFlexBall(Ball):
    """A :class:`Ball` with DFlex's spring instead of MuJoCo's (``dflex/sim.py``, NVlabs/DiffRL 6b8d695): the torque
    ``-stiffness r`` with ``r = sin(theta/2) axis`` the vector part of the rotation from ``springref`` (its quaternion
    not turned to the shorter way round), about half MuJoCo's rotation-vector spring ``-stiffness theta axis`` near
    rest. It is conservative: its potential is ``2 stiffness (1 - w)``, ``w`` that rotation's scalar part (the torque
    is the same in the body's frame as in DFlex's parent-side one, since the axis is the rotation's own). What reads
    DFlex's models with its fidelity options uses it (:mod:`lagrange.tasks.snu`)."""

    def spring(self, q, ref):
        ref = al.normalize_quat(jnp.asarray(ref, q.dtype))
        return al.quat_multiply(ref * jnp.asarray([1.0, -1.0, -1.0, -1.0], q.dtype), al.normalize_quat(q))[..., 1:]

    def spring_energy(self, q, ref):
        ref = al.normalize_quat(jnp.asarray(ref, q.dtype))
        w = al.quat_multiply(ref * jnp.asarray([1.0, -1.0, -1.0, -1.0], q.dtype), al.normalize_quat(q))[..., 0]
        return 4.0 * (1.0 - w)


class Free(AbstractJoint):
    """A free joint: the body's origin at ``q[:3]`` [m] in the world and its orientation the unit quaternion
    ``q[3:]``; its velocities the origin's linear velocity in the world frame and the angular velocity in the body's
    frame (MuJoCo's ``<freejoint/>``). Only the first joint of a body that hangs from the world; the tree's
    reference point is then that body's origin.

    Args:
        damping, armature, stiffness: see :class:`AbstractJoint`, the same for each of the six velocities.
        springref: the spring's rest coordinates, shape ``(7,)`` (default the body's pose as written).
        name: the joint's name (MJCF's and URDF's), by which :meth:`lagrange.Tree.joint_index` finds it; static.
    """

    nq: ClassVar[int] = 7
    nv: ClassVar[int] = 6
    range: ClassVar[None] = None  # a free joint has no limit
    damping: Float[ArrayLike, ""]
    armature: Float[ArrayLike, ""]
    stiffness: Float[ArrayLike, ""]
    springref: Float[ArrayLike, "7"] | None
    name: str | None = eqx.field(static=True)

    def __init__(self, *, damping=0.0, armature=0.0, stiffness=0.0, springref=None, name: str | None = None):
        self.name = _name("Free", name)
        self.damping = check_array("Free.damping", damping, nonnegative=True)
        self.armature = check_array("Free.armature", armature, nonnegative=True)
        self.stiffness = check_array("Free.stiffness", stiffness, nonnegative=True)
        self.springref = None if springref is None else check_array("Free.springref", springref, (7,))

    places_body: ClassVar[bool] = True

    @classmethod
    def local(cls, joints, q):
        # the orientation only: the position is the tree's reference point (q[:3], taken by the kinematics)
        return al.quat_to_matrix(al.normalize_quat(q[..., 3:])), jnp.zeros_like(q[..., :3])

    @classmethod
    def subspace(cls, joints, R, p):
        zero = jnp.zeros_like(R)
        linear = jnp.concatenate([zero, jnp.broadcast_to(al.eye3(R.dtype), R.shape)], axis=-1)
        angular = jnp.concatenate([jnp.swapaxes(R, -1, -2), zero], axis=-1)
        return jnp.concatenate([linear, angular], axis=-2)

    def integrate(self, q, v, h):
        return jnp.concatenate([q[..., :3] + h * v[..., :3], al.quat_integrate(q[..., 3:], v[..., 3:], h)], axis=-1)

    def spring(self, q, ref):
        ref = jnp.asarray(ref, q.dtype)
        return jnp.concatenate([q[..., :3] - ref[:3], al.quat_difference(al.normalize_quat(q[..., 3:]),
                                                                        al.normalize_quat(ref[3:]))], axis=-1)

    def neutral(self):
        return np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def _static_point(name: str, pos) -> tuple[float, float, float]:
    """A joint's anchor as three Python floats (static), checked finite; a traced value is refused by name."""
    if isinstance(pos, jax.core.Tracer) or any(isinstance(x, jax.core.Tracer) for x in np.ravel(np.asarray(pos,
                                                                                                     dtype=object))):
        raise TypeError(f"{name} is static (the joint's place, as its axis is): give three numbers, not a traced value")
    return tuple(float(x) for x in np.asarray(check_array(name, pos, (3,)), float))


def _stack(values, dtype):
    """Per-joint parameters stacked along a new first axis in ``dtype`` (the coordinates', so that static float64
    constants do not promote a float32 tree): in NumPy when every one is concrete (no JAX operation)."""
    if any(isinstance(v, jax.core.Tracer) for v in values):
        return jnp.stack([jnp.asarray(v) for v in values]).astype(dtype)
    return np.stack([np.asarray(v) for v in values]).astype(dtype)  # concrete: the arithmetic runs while tracing


def _stacked(joints, dtype):
    """``(axis, pos, ref)`` of hinges or slides, stacked in ``dtype``: ``(n, 3)`` (static), ``(n, 3)``, ``(n,)``."""
    return (np.array([j.axis for j in joints], dtype), _stack([j.pos for j in joints], dtype),
            _stack([j.ref for j in joints], dtype))


JOINTS = (Hinge, Slide, Ball, Free)
"""The joint kinds."""
