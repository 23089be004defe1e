"""A planar link: one joint (revolute or prismatic) and the physical parameters of the body it moves, the unit of
which :class:`lagrange.chain.Chain` builds a planar tree (the conventions: :mod:`lagrange.chain`). The lowering of a
planar tree to the planar backend (:mod:`lagrange.planar.lower`) speaks in links too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import equinox as eqx
import numpy as np
from jaxtyping import ArrayLike, Float

from lagrange.model.checks import check_pair, check_point, check_points, check_scalar

__all__ = ["JOINTS", "Link", "WORLD"]

JOINTS = ("revolute", "prismatic")
"""The joint kinds a :class:`Link` may have."""

WORLD = -1
"""The ``parent`` of a link that hangs from the world."""


class Link(eqx.Module):
    """One link of a planar chain or tree and the joint that connects it to its parent.

    Every parameter is a real scalar (a Python number, or a 0-d array; traced values are accepted
    and checked once they are known).

    Args:
        joint: ``"revolute"`` or ``"prismatic"``.
        mass: link mass [kg], >= 0.
        length: distance from this joint to the next one [m], >= 0.
        com: distance from the joint to the centre of mass along the link [m]; default ``length/2``.
        com_normal: distance of the centre of mass from the link's line, along its normal ``e`` [m];
            default 0.
        inertia: moment of inertia about the centre of mass [kg m^2], >= 0; default ``mass length^2/12``.
        axis: for a prismatic joint, the slide direction's angle relative to the parent's normal
            ``e`` [rad]; static.
        damping: viscous joint damping [N s/m or N m s/rad], >= 0.
        armature: rotor inertia added to the joint's diagonal of M [kg m^2 or kg], >= 0.
        gear: if given (> 0), the joint is actuated with generalized force ``gear * u``; ``None``
            (the default) leaves it passive. To reverse a motor, negate its control.
        offset: the angle of this link's frame relative to its parent's at ``q = 0`` [rad]; static.
        control_range: ``(lo, hi)`` with ``lo < hi``: the control is clamped into it before the gear
            (MuJoCo's ``ctrlrange``); ``None`` (the default) leaves it unbounded. Only for an actuated
            joint; static.
        parent: the link this one hangs from: the index of a link listed before it, or :data:`WORLD` (-1);
            ``None`` (the default) is the link listed just before it (the world for the first link); static.
        attach: where the joint sits on the parent, ``(x, z)`` in the parent's frame [m] (its local x along
            ``e``, local z against ``d``; the world's axes for a link of the world); ``None`` (the default) is the
            parent's tip ``(0, -length)`` (the origin for a link of the world).
        stiffness: joint spring [N m/rad or N/m], >= 0: generalized force ``-stiffness (q - springref)``.
        springref: the spring's rest coordinate [rad or m] (MuJoCo's ``springref``).
        sense: ``1`` (the default) or ``-1``: the way a revolute joint turns, ``phi_i = phi_parent + sense q_i``
            (``-1``: a MuJoCo hinge about ``+y`` among hinges about ``-y``, as in the Gymnasium hopper's root);
            static. A prismatic joint's direction is its ``axis`` (``sense`` must be 1).
        range: ``(lower, upper)`` with ``lower < upper`` [rad or m]: the joint's range, enforced by the chain's
            :class:`lagrange.PenaltyLimits`; ``None`` (the default): unlimited; static.
        contacts: contact points ``(x, z, radius)`` in this link's frame [m] (a capsule's two end points, a
            sphere's centre, each with its radius), pressed by the chain's :class:`lagrange.PenaltyContact`
            against the ground; ``()`` (the default): this link cannot touch; static.
    """

    joint: str = eqx.field(static=True)
    mass: Float[ArrayLike, ""]
    length: Float[ArrayLike, ""] = 0.0
    com: Float[ArrayLike, ""] | None = None
    inertia: Float[ArrayLike, ""] | None = None
    axis: float = eqx.field(static=True, default=0.0)
    damping: Float[ArrayLike, ""] = 0.0
    armature: Float[ArrayLike, ""] = 0.0
    gear: Float[ArrayLike, ""] | None = None
    com_normal: Float[ArrayLike, ""] = 0.0
    offset: float = eqx.field(static=True, default=0.0)
    control_range: tuple[float, float] | None = eqx.field(static=True, default=None)
    parent: int | None = eqx.field(static=True, default=None)
    attach: Float[ArrayLike, "2"] | None = None
    stiffness: Float[ArrayLike, ""] = 0.0
    springref: Float[ArrayLike, ""] = 0.0
    sense: int = eqx.field(static=True, default=1)
    range: tuple[float, float] | None = eqx.field(static=True, default=None)
    contacts: tuple[tuple[float, float, float], ...] = eqx.field(static=True, default=())

    def __init__(
        self,
        joint: str,
        mass: Float[ArrayLike, ""],
        length: Float[ArrayLike, ""] = 0.0,
        com: Float[ArrayLike, ""] | None = None,
        inertia: Float[ArrayLike, ""] | None = None,
        axis: float = 0.0,
        damping: Float[ArrayLike, ""] = 0.0,
        armature: Float[ArrayLike, ""] = 0.0,
        gear: Float[ArrayLike, ""] | None = None,
        *,
        com_normal: Float[ArrayLike, ""] = 0.0,
        offset: float = 0.0,
        control_range: tuple[float, float] | None = None,
        parent: int | None = None,
        attach: Float[ArrayLike, "2"] | None = None,
        stiffness: Float[ArrayLike, ""] = 0.0,
        springref: Float[ArrayLike, ""] = 0.0,
        sense: int = 1,
        range: tuple[float, float] | None = None,
        contacts: Sequence[tuple[float, float, float]] = (),
    ):
        if isinstance(joint, np.str_):
            joint = str(joint)
        if not isinstance(joint, str) or joint not in JOINTS:
            raise ValueError(f"Link.joint must be one of {JOINTS}, got {joint!r}")
        check_scalar("axis", axis)
        check_scalar("offset", offset)
        if control_range is not None:
            try:
                lo, hi = (float(x) for x in control_range)
            except (TypeError, ValueError) as err:
                raise TypeError("Link.control_range must be a pair (lo, hi) of numbers or None, "
                                f"got {control_range!r}") from err
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"Link.control_range must be finite with lo < hi, got {control_range!r}")
            if gear is None:
                raise ValueError("Link.control_range is given but the joint is not actuated (gear=None); give a gear")
            control_range = (lo, hi)
        if parent is not None:
            if isinstance(parent, (bool, np.bool_)) or not isinstance(parent, (int, np.integer)) or parent < WORLD:
                raise ValueError(f"Link.parent must be None (the link listed before it), -1 (the world) or the index "
                                 f"of a link listed before it, got {parent!r}")
            parent = int(parent)
        if isinstance(sense, (bool, np.bool_)) or sense not in (1, -1):
            raise ValueError(f"Link.sense must be 1 or -1, got {sense!r}")
        if joint == "prismatic" and sense != 1:
            raise ValueError("Link.sense must be 1 for a prismatic joint; reverse a slide by turning its axis by pi")
        self.joint = joint
        self.mass = mass
        self.length = length
        self.com = com
        self.inertia = inertia
        self.axis = float(axis)
        self.damping = damping
        self.armature = armature
        self.gear = gear
        self.com_normal = com_normal
        self.offset = float(offset)
        self.control_range = control_range
        self.parent = parent
        self.attach = attach
        self.stiffness = stiffness
        self.springref = springref
        self.sense = int(sense)
        self.range = check_pair("range", range)
        self.contacts = check_points("contacts", contacts)

    def __check_init__(self):
        if not isinstance(self.joint, str) or self.joint not in JOINTS:
            raise ValueError(f"Link.joint must be one of {JOINTS}, got {self.joint!r}")
        check_scalar("mass", self.mass, nonnegative=True)
        check_scalar("length", self.length, nonnegative=True)
        check_scalar("com", self.com, optional=True)
        check_scalar("inertia", self.inertia, nonnegative=True, optional=True)
        check_scalar("axis", self.axis)
        check_scalar("damping", self.damping, nonnegative=True)
        check_scalar("armature", self.armature, nonnegative=True)
        check_scalar("gear", self.gear, positive=True, optional=True)
        check_scalar("com_normal", self.com_normal)
        check_scalar("stiffness", self.stiffness, nonnegative=True)
        check_scalar("springref", self.springref)
        check_point("attach", self.attach)
