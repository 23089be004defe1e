"""Planar chains and trees written link by link (a serial chain is the special case): a :class:`Chain` is a
:class:`lagrange.Tree` whose bodies are the links, built from :class:`Link` s in a few lines.

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

As a tree (the docs' conventions page): link ``i`` is body ``i``, its frame the link's (local ``-z`` along ``d``,
local ``+x`` along ``e``, the plane the world's x-z plane), placed at its ``attach`` point ``(x, 0, z)`` (default the
parent's tip ``(0, 0, -length_parent)``) and turned by its ``offset`` about ``(0, -1, 0)``; a revolute joint is a
:class:`~lagrange.model.joints.Hinge` about ``(0, -sense, 0)``, a prismatic one a
:class:`~lagrange.model.joints.Slide` along ``(cos a, 0, sin a)`` with ``a = axis - offset``; the centre of mass sits at
``(com_normal, 0, -com)``, the rotational inertia is ``diag(I, I, I)`` (only the moment about the normal ever acts),
the tip at ``(0, 0, -length)``, a contact point at ``(x, 0, z)``; each actuated joint has a
:class:`~lagrange.model.tree.Motor`, and gravity is ``(0, 0, -gravity)``. The tree is planar
(:attr:`lagrange.Tree.planar`), so its dynamics are the planar backend's (:mod:`lagrange.planar`), which lowers it back
to these links while tracing.

Building a chain checks its parameters and computes nothing: no dynamics and no JAX operation (concrete values are
transferred with ``jax.device_put``). A mass matrix that is singular at every configuration because a joint moves
nothing is refused here; one that is singular only at some configurations is reported by
:func:`lagrange.dynamics.forward_dynamics` and :func:`lagrange.integrate.simulate` when it is met.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from lagrange.math.scalar import cos_sin
from lagrange.model.checks import (check_every_joint_moves_something, check_laws, check_parents, concrete, traced,
                                   value_of)
from lagrange.model.contact import PenaltyContact
from lagrange.model.joints import Hinge, Slide
from lagrange.model.limits import PenaltyLimits
from lagrange.model.link import JOINTS, WORLD, Link
from lagrange.model.tree import Body, Motor, Tree

__all__ = ["Chain", "JOINTS", "Link", "WORLD"]

class Chain(Tree):
    """A planar kinematic tree of ``n`` links, ``m`` of them actuated, written link by link: a :class:`lagrange.Tree`
    (a serial chain by default).

    Its bodies, joints and motors are the links' (the module docstring says how), so every function of
    :mod:`lagrange` takes it as it takes any tree, ``q`` and ``qd`` have ``n`` entries (``nq = nv = n``) and
    ``jax.grad`` with respect to it gives a tree of the same shape: ``grad.mass`` the links' masses,
    ``grad.bodies[i]`` the rest of link ``i``'s. Differentiate with respect to a link's length (its children's attach
    points and its tip) through the builder: ``jax.grad(lambda L: loss(Chain([..., Link("revolute", m, L), ...])))(L)``.

    Args:
        links: a non-empty sequence of :class:`Link`, parents before their children.
        gravity: gravitational acceleration [m/s^2] along -z; finite.
        contact: the ground contact law (:class:`lagrange.PenaltyContact`) pressing the links' ``contacts`` points;
            ``None`` (the default): no contact. Given exactly when some link has contact points.
        limits: the joint limit law (:class:`lagrange.PenaltyLimits`) enforcing the links' ``range``; ``None`` (the
            default): no limits. Given exactly when some link has a range.

    Raises:
        TypeError, ValueError: naming the bad field, for a parameter of the wrong type, sign or
            shape, a non-finite one, an unknown joint kind, a parent that is not the world or a link listed
            before its child, or a joint that moves no mass, inertia or armature at any configuration (a mass
            matrix singular everywhere).
    """

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
        check_laws(contact, limits, tuple(i for i, lk in enumerate(links) for _ in lk.contacts),
                   tuple(i for i, lk in enumerate(links) if lk.range is not None))
        bodies = [_body(i, lk, None if parents[i] == WORLD else links[parents[i]], parents[i])
                  for i, lk in enumerate(links)]
        motors = [Motor(i, lk.gear, lk.control_range) for i, lk in enumerate(links) if lk.gear is not None]
        super().__init__(bodies, (0.0, 0.0, _negative(gravity)), motors=motors, contact=contact,
                         limits=limits)

    def links(self) -> tuple[Link, ...]:
        """The chain as its links, for editing and re-building: the planar backend's reading of the tree
        (:func:`lagrange.planar.lower.lower`).

        Returns:
            A tuple of :class:`Link`, one per link, from which ``Chain(links, gravity, contact=chain.contact,
            limits=chain.limits)`` rebuilds the chain.
        """
        from lagrange.planar.lower import lower

        return lower(self).links()


def _negative(x):
    return -x if traced(x) else -np.asarray(x, float)


def _vector(*xs):
    """Three scalars as a vector: NumPy when all are concrete (no JAX operation), else ``jax.numpy``."""
    if traced(*xs):
        return jnp.stack([jnp.asarray(x, jax.dtypes.canonicalize_dtype(float)) for x in xs])
    return np.array([float(np.asarray(x)) for x in xs])


def _turn(angle: float) -> tuple[float, float, float, float]:
    """The quaternion of a turn by ``angle`` about ``(0, -1, 0)``, entries within 1e-15 of 0 exactly 0: of the unit
    quaternions within two units in the last place, one whose angle ``2 atan2(-y, w)`` reads back exactly, so that the
    planar backend finds the link's ``offset`` as it was given."""
    c, s = math.cos(angle / 2), -math.sin(angle / 2)
    c, s = (0.0 if abs(c) < 1e-15 else c), (0.0 if abs(s) < 1e-15 else s)
    for dc in (0, 1, -1, 2, -2):
        for ds in (0, 1, -1, 2, -2):
            c2, s2 = _ulps(c, dc), _ulps(s, ds)
            if 2.0 * math.atan2(-s2, c2) == angle and abs(math.hypot(c2, s2) - 1.0) <= 4 * np.finfo(float).eps:
                return (c2, 0.0, s2, 0.0)
    return (c, 0.0, s, 0.0)


def _direction(axis: float, offset: float) -> tuple[float, float, float]:
    """A slide's direction ``(cos a, 0, sin a)``, ``a = axis - offset``, in its link's frame: of the unit vectors within
    two units in the last place, one whose angle ``atan2`` reads back to ``axis`` exactly with the offset added, as
    :func:`_turn` does for the offset."""
    c, s = cos_sin(axis - offset)
    for dc in (0, 1, -1, 2, -2):
        for ds in (0, 1, -1, 2, -2):
            c2, s2 = _ulps(c, dc), _ulps(s, ds)
            back = math.remainder(math.atan2(s2, c2) + offset, 2 * math.pi) + 0.0
            if back == math.remainder(axis, 2 * math.pi) and abs(math.hypot(c2, s2) - 1.0) <= 4 * np.finfo(float).eps:
                return (c2, 0.0, s2)
    return (c, 0.0, s)


def _ulps(x: float, k: int) -> float:
    for _ in range(abs(k)):
        x = math.nextafter(x, math.inf if k > 0 else -math.inf)
    return x


def _body(i: int, link: Link, parent: Link | None, p: int) -> Body:
    """Link ``i`` as body ``i`` (the module docstring's mapping)."""
    if link.attach is not None:
        x, z = (link.attach[k] for k in range(2))
        pos = _vector(x, 0.0, z)
    else:
        pos = _vector(0.0, 0.0, 0.0 if parent is None else _negative(parent.length))
    com = value_of(link.length) / 2 if link.com is None else link.com
    inertia = (value_of(link.mass) * value_of(link.length) ** 2 / 12) if link.inertia is None else link.inertia
    inertia = jnp.eye(3) * inertia if traced(inertia) else np.eye(3) * float(np.asarray(inertia))
    common = dict(damping=link.damping, armature=link.armature, stiffness=link.stiffness, springref=link.springref,
                  range=link.range)
    if link.joint == "revolute":
        joint = Hinge((0.0, -float(link.sense), 0.0), **common)
    else:
        joint = Slide(_direction(link.axis, link.offset), **common)
    return Body(link.mass, inertia, _vector(link.com_normal, 0.0, _negative(com)), joints=[joint],
                parent=p, pos=pos, quat=_turn(link.offset), contacts=[(x, 0.0, z, r) for x, z, r in link.contacts],
                tip=_vector(0.0, 0.0, _negative(link.length)), name=f"link{i}")
