"""Planar kinematic trees (a serial chain is the special case): links, joints and their physical parameters.

Conventions (see also the docs' "Conventions" page):

- The model lives in the vertical x-z plane; gravity points along -z.
- Every body frame has an origin ``p`` and an angle ``phi``. The link direction is
  ``d(phi) = (sin phi, -cos phi)`` and its normal ``e(phi) = (cos phi, sin phi)``; a point given in a link's frame as
  ``(x, z)`` sits at ``p + x e(phi) - z d(phi)`` (the frame's local x along ``e``, its local z against ``d``, as the
  body frames of the MJCF :func:`lagrange.interop.mjcf.to_mjcf` writes). The world frame has ``p = 0`` and
  ``phi = 0``: ``d`` points down and ``e`` along +x, so its local axes are the world's.
- Every link has a parent: the world, or a link listed before it (links are listed parents first). By default a link's
  parent is the link listed before it (the world for the first), which makes a serial chain; several links may share
  a parent (branches) and several may hang from the world (a forest).
- Link ``i`` starts at its ``attach`` point in its parent's frame, by default the parent's tip
  ``(0, -length_parent)`` (the world's origin for a link of the world): ``p_i = p_parent + l_parent d(phi_parent)``.
- ``joint="revolute"``: ``phi_i = phi_parent + q_i`` (``- q_i`` for a joint of ``sense=-1``). ``joint="prismatic"``:
  ``phi_i = phi_parent`` and the frame slides by ``q_i`` along ``e(phi_parent + axis)``; a prismatic joint of the world
  with ``axis=0`` is a cart on the x axis.
- ``offset`` (static, default 0) turns a link's frame against its parent's at ``q = 0``:
  ``phi_i = phi_parent + offset_i (+ q_i)``, so a revolute joint's zero need not hang along its parent (an upright
  link is ``offset = pi``).
- The centre of mass is at ``p_i + com d(phi_i) + com_normal e(phi_i)`` (default ``com = length / 2``,
  ``com_normal = 0``); ``inertia`` is
  the moment of inertia about the centre of mass, normal to the plane (default
  ``mass length^2 / 12``, a thin rod). ``damping`` is viscous (generalized force
  ``-damping qd_i``), ``stiffness`` a joint spring (generalized force ``-stiffness (q_i - springref)``),
  ``armature`` is added to ``M_ii``, and ``gear`` makes the joint actuated
  (generalized force ``gear u_k``, ``k`` counting actuated joints in order); a ``control_range``
  ``(lo, hi)`` clamps ``u_k`` into it before the gear, as MuJoCo clamps a limited ``ctrl``.

Structure is static: the number of links, their parents, the joint kinds, the prismatic axes, the frame
offsets, the control ranges, which joints are actuated and which optional terms exist. A term given as exactly zero
(no damping, no spring, no armature, zero gravity, an attach point left at its default) is structurally absent and
costs nothing in the compiled program; give it a non-zero value if you want to differentiate with respect to it.

Building a chain checks its parameters and stacks them, and computes nothing: no dynamics and no
JAX operation (concrete values are stacked in NumPy and transferred with ``jax.device_put``). A
mass matrix that is singular at every configuration because a joint moves nothing is refused here;
one that is singular only at some configurations is reported by
:func:`lagrange.dynamics.forward_dynamics` and :func:`lagrange.integrate.simulate` when it is met.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.model.checks import (check_every_joint_moves_something, check_laws, check_pair, check_parents,
check_point,
                             check_points, check_scalar, concrete, is_zero, stack, stack_points, value_of)
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits

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


class Chain(eqx.Module):
    """An immutable planar kinematic tree of ``n`` links, ``m`` of them actuated; a serial chain by default.

    Physical parameters are array leaves of shape ``(n,)`` (``gear``: ``(m,)``; ``gravity``: ``()``; ``attach``:
    ``(k, 2)`` for the ``k`` links with an attach point of their own), so ``jax.grad``/``eqx.filter_grad`` with
    respect to masses, lengths, inertias, damping, springs, attach points and gravity works. Structure is static,
    and construction computes nothing (see the module docstring).

    Args:
        links: a non-empty sequence of :class:`Link`, parents before their children.
        gravity: gravitational acceleration [m/s^2] along -z; finite.
        contact: the ground contact law (:class:`lagrange.PenaltyContact`) pressing the links' ``contacts`` points;
            ``None`` (the default): no contact. Given exactly when some link has contact points.
        limits: the joint limit law (:class:`lagrange.PenaltyLimits`) enforcing the links' ``range``; ``None`` (the
            default): no limits. Given exactly when some link has a range.

    Attributes:
        mass: link masses [kg], shape ``(n,)``.
        length: link lengths, joint to tip [m], shape ``(n,)``.
        com: centre-of-mass distances along each link [m], shape ``(n,)``.
        inertia: moments of inertia about the centres of mass [kg m^2], shape ``(n,)``.
        damping: joint damping [N s/m or N m s/rad], shape ``(n,)``; ``None`` when no joint is damped.
        armature: joint armature [kg or kg m^2], shape ``(n,)``; ``None`` when no joint has one.
        gear: the actuated joints' gears, shape ``(m,)``; ``None`` for an unactuated chain.
        gravity: gravitational acceleration [m/s^2], shape ``()``; ``None`` for zero gravity.
        com_normal: centre-of-mass offsets along each link's normal [m], shape ``(n,)``; ``None`` when all are 0.
        attach: the attach points ``(x, z)`` [m] of the links in ``attached``, shape ``(len(attached), 2)``; ``None``
            when every link sits at its parent's tip (or the world's origin).
        stiffness: joint spring stiffnesses [N m/rad or N/m], shape ``(n,)``; ``None`` without springs.
        springref: the springs' rest coordinates [rad or m], shape ``(n,)``; ``None`` without springs.
        ranges: the ranges ``(lower, upper)`` [rad or m] of the links in ``limited``, shape ``(len(limited), 2)``;
            ``None`` without limits.
        contact_points: the contact points ``(x, z, radius)`` [m] in their links' frames, shape ``(k, 3)``;
            ``None`` without contact.
        contact: the ground contact law, or ``None``.
        limits: the joint limit law, or ``None``.
        joints: each link's joint kind, ``"revolute"`` or ``"prismatic"`` (static).
        axes: each prismatic joint's slide angle relative to its parent's normal [rad] (0 for revolute joints;
            static).
        offsets: each link frame's angle against its parent's at ``q = 0`` [rad] (static).
        control_ranges: per actuated joint, its ``(lo, hi)`` or ``None``; ``None`` when no control is clamped
            (static).
        actuated: the actuated links, in order: control ``k`` drives link ``actuated[k]`` (static).
        damped: the links whose joint is damped (static).
        armatured: the links whose joint has armature (static).
        parents: each link's parent, ``-1`` for the world (static).
        attached: the links with an ``attach`` point of their own (the others sit at their parent's tip), in order;
            ``attach[k]`` belongs to link ``attached[k]`` (static).
        sprung: the links whose joint has a spring (``stiffness > 0``) (static).
        senses: each joint's ``sense``, ``1`` or ``-1`` (static).
        limited: the links with a ``range``; ``ranges[k]`` is link ``limited[k]``'s ``(lower, upper)`` (static).
        contact_links: the link of each contact point; ``contact_points[k]`` is point ``k``'s ``(x, z, radius)`` in
            its link's frame (static).

    Raises:
        TypeError, ValueError: naming the bad field, for a parameter of the wrong type, sign or
            shape, a non-finite one, an unknown joint kind, a parent that is not the world or a link listed
            before its child, or a joint that moves no mass, inertia or armature at any configuration (a mass
            matrix singular everywhere).
    """

    mass: Float[Array, " n"]
    length: Float[Array, " n"]
    com: Float[Array, " n"]
    inertia: Float[Array, " n"]
    damping: Float[Array, " n"] | None
    armature: Float[Array, " n"] | None
    gear: Float[Array, " m"] | None
    gravity: Float[Array, ""] | None
    com_normal: Float[Array, " n"] | None
    attach: Float[Array, "k 2"] | None
    stiffness: Float[Array, " n"] | None
    springref: Float[Array, " n"] | None
    ranges: Float[Array, "l 2"] | None
    contact_points: Float[Array, "k 3"] | None
    contact: PenaltyContact | None
    limits: PenaltyLimits | None
    joints: tuple[str, ...] = eqx.field(static=True)
    axes: tuple[float, ...] = eqx.field(static=True)
    offsets: tuple[float, ...] = eqx.field(static=True)
    control_ranges: tuple[tuple[float, float] | None, ...] | None = eqx.field(static=True)
    actuated: tuple[int, ...] = eqx.field(static=True)
    damped: tuple[int, ...] = eqx.field(static=True)
    armatured: tuple[int, ...] = eqx.field(static=True)
    parents: tuple[int, ...] = eqx.field(static=True)
    attached: tuple[int, ...] = eqx.field(static=True)
    sprung: tuple[int, ...] = eqx.field(static=True)
    senses: tuple[int, ...] = eqx.field(static=True)
    limited: tuple[int, ...] = eqx.field(static=True)
    contact_links: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, links: Sequence[Link], gravity: Float[ArrayLike, ""] = 9.81, *,
                 contact: PenaltyContact | None = None, limits: PenaltyLimits | None = None):
        if isinstance(links, Link):
            raise TypeError("Chain.links must be a sequence of Link, got a single Link; wrap it in a list")
        links = tuple(links)
        if len(links) == 0:
            raise ValueError("Chain.links must contain at least one Link, got none")
        for i, link in enumerate(links):
            if not isinstance(link, Link):
                raise TypeError(f"Chain.links[{i}] must be a lagrange.chain.Link, got {type(link).__name__}")
        if gravity is None or isinstance(gravity, (bool, str)):
            raise TypeError(f"Chain.gravity must be a real number (use 0.0 for none), got {gravity!r}")
        g = concrete(gravity)
        if g is not None:
            if g.shape != ():
                raise ValueError(f"Chain.gravity must be a scalar, got shape {g.shape}")
            if not math.isfinite(float(g)):
                raise ValueError(f"Chain.gravity must be finite, got {float(g)}")
        parents = check_parents(links)
        check_every_joint_moves_something(links, parents)

        dtype = jax.dtypes.canonicalize_dtype(float)
        self.mass = stack([lk.mass for lk in links], dtype)
        self.length = stack([lk.length for lk in links], dtype)
        self.com = stack([value_of(lk.length) / 2 if lk.com is None else lk.com for lk in links], dtype)
        self.inertia = stack([value_of(lk.mass) * value_of(lk.length) ** 2 / 12 if lk.inertia is None else lk.inertia
                              for lk in links], dtype)
        self.joints = tuple(lk.joint for lk in links)
        self.axes = tuple(float(lk.axis) for lk in links)
        self.offsets = tuple(float(lk.offset) for lk in links)
        self.com_normal = (
            None if all(is_zero(lk.com_normal) for lk in links) else stack([lk.com_normal for lk in links], dtype)
        )
        self.actuated = tuple(i for i, lk in enumerate(links) if lk.gear is not None)
        self.damped = tuple(i for i, lk in enumerate(links) if not is_zero(lk.damping))
        self.armatured = tuple(i for i, lk in enumerate(links) if not is_zero(lk.armature))
        self.damping = stack([lk.damping for lk in links], dtype) if self.damped else None
        self.armature = stack([lk.armature for lk in links], dtype) if self.armatured else None
        self.gear = stack([links[i].gear for i in self.actuated], dtype) if self.actuated else None
        self.gravity = None if is_zero(gravity) else stack(gravity, dtype)
        ranges = tuple(links[i].control_range for i in self.actuated)
        self.control_ranges = ranges if any(r is not None for r in ranges) else None
        self.parents = parents
        self.attached = tuple(i for i, lk in enumerate(links) if lk.attach is not None)
        self.attach = stack_points([links[i].attach for i in self.attached], dtype) if self.attached else None
        self.sprung = tuple(i for i, lk in enumerate(links) if not is_zero(lk.stiffness))
        self.stiffness = stack([lk.stiffness for lk in links], dtype) if self.sprung else None
        self.springref = stack([lk.springref for lk in links], dtype) if self.sprung else None
        self.senses = tuple(lk.sense for lk in links)
        self.limited = tuple(i for i, lk in enumerate(links) if lk.range is not None)
        self.ranges = stack_points([links[i].range for i in self.limited], dtype) if self.limited else None
        self.contact_links = tuple(i for i, lk in enumerate(links) for _ in lk.contacts)
        self.contact_points = (stack_points([p for lk in links for p in lk.contacts], dtype)
                               if self.contact_links else None)
        check_laws(contact, limits, self.contact_links, self.limited)
        self.contact, self.limits = contact, limits

    def frame_offsets(self) -> tuple[float, ...]:
        """Each link frame's angle at ``q = 0``: the sum of the offsets on its path from the world. Static.

        Returns:
            One angle [rad] per link: ``phi_i = offset_sum_i + sum_j sense_j q_j`` over the revolute joints ``j`` on
            link ``i``'s path.
        """
        out: list[float] = []
        for i, off in enumerate(self.offsets):
            out.append(off if self.parents[i] == WORLD else out[self.parents[i]] + off)
        return tuple(out)

    @property
    def n(self) -> int:
        """Number of generalized coordinates (links)."""
        return len(self.joints)

    @property
    def m(self) -> int:
        """Number of actuated joints (controls)."""
        return len(self.actuated)

    @property
    def serial(self) -> bool:
        """Whether the links form one serial chain from the world (each the parent of the next)."""
        return self.parents == tuple(range(-1, self.n - 1))

    def children(self, i: int) -> tuple[int, ...]:
        """The links whose parent is link ``i``, in order. Static.

        Args:
            i: a link's index, or ``-1`` for the world.

        Returns:
            The children's indices (the links of the world for ``i = -1``).
        """
        return tuple(k for k, p in enumerate(self.parents) if p == i)

    def path(self, i: int) -> tuple[int, ...]:
        """The links from the world to link ``i``, ``i`` included, in order. Static.

        Args:
            i: a link's index.

        Returns:
            The indices on the path, the link of the world first and ``i`` last.
        """
        out = []
        while i != WORLD:
            out.append(i)
            i = self.parents[i]
        return tuple(reversed(out))

    def segments(self) -> tuple[tuple[int, int], ...]:
        """The tree as serial segments: runs of links, each the only child of the one before. Static.

        A segment ends at a link with no child or several, or one whose child is not listed next. The parent of a
        segment's first link is the world or the last link of an earlier segment.

        Returns:
            ``(start, stop)`` pairs in order, each the links ``start, ..., stop - 1``; ``((0, n),)`` for a serial chain.
        """
        starts = [i for i in range(self.n) if i == 0 or self.parents[i] != i - 1 or len(self.children(i - 1)) != 1]
        return tuple(zip(starts, starts[1:] + [self.n]))

    def links(self) -> tuple[Link, ...]:
        """The chain as its links, for editing and re-building.

        Returns:
            A tuple of :class:`Link`, one per link, from which ``Chain(links, gravity, contact=chain.contact,
            limits=chain.limits)`` rebuilds the chain.
        """
        out = []
        k = {j: i for i, j in enumerate(self.actuated)}
        at = {j: i for i, j in enumerate(self.attached)}
        per = lambda x, i, default=0.0: default if x is None or i is None else x[i]  # noqa: E731
        for i, joint in enumerate(self.joints):
            ranges = None if (i not in k or self.control_ranges is None) else self.control_ranges[k[i]]
            out.append(Link(
                joint, self.mass[i], self.length[i], self.com[i], self.inertia[i], axis=self.axes[i],
                damping=per(self.damping, i), armature=per(self.armature, i), gear=per(self.gear, k.get(i), None),
                com_normal=per(self.com_normal, i), offset=self.offsets[i], control_range=ranges,
                parent=None if self.parents[i] == i - 1 else self.parents[i], attach=per(self.attach, at.get(i), None),
                stiffness=per(self.stiffness, i), springref=per(self.springref, i), sense=self.senses[i],
                range=None if i not in self.limited else tuple(float(x) for x in self.ranges[self.limited.index(i)]),
                contacts=tuple(tuple(float(x) for x in self.contact_points[c])
                               for c, link in enumerate(self.contact_links) if link == i)))
        return tuple(out)
