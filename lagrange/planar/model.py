"""The planar backend's model: a planar tree as per-link arrays, lowered from a :class:`lagrange.Tree` while tracing
(:mod:`lagrange.planar.lower`) and read by the unrolled and recursive derivations, and the base of those two backends
(:class:`AbstractPlanar`; :class:`lagrange.planar.unrolled.Unrolled` and :class:`lagrange.planar.recursive.Recursive`
derive the equations).

A :class:`PlanarChain` is what a planar chain was when it was a model of its own: ``n`` links, each a revolute or
prismatic joint, with per-link arrays of mass, length, centre of mass, inertia, damping, springs, ... and its
structure (parents, joint kinds, frame offsets, which terms exist) static. Its conventions are those of
:mod:`lagrange.chain`. Built by the lowering with its parameters as NumPy arrays when they are concrete (so that
their products fold while tracing) and as JAX arrays when they are traced; never a user's model.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.backend import AbstractBackend
from lagrange.forces import actuation_matrix, clamp_controls
from lagrange.model.link import WORLD, Link
from lagrange.model.checks import check_laws, check_parents, is_zero, value_of
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits

__all__ = ["AbstractPlanar", "PlanarChain", "WORLD"]


def stack(values, dtype):
    """Per-link scalars (or one scalar) as an array of ``dtype``: NumPy when every value is concrete (so that the
    derivations fold them while tracing), ``jax.numpy`` when one is traced."""
    if isinstance(values, (list, tuple)):
        if any(isinstance(v, jax.core.Tracer) for v in values):
            return jnp.stack([jnp.asarray(v, dtype=dtype) for v in values])
        return np.stack([np.asarray(v, dtype=dtype) for v in values])
    if isinstance(values, jax.core.Tracer):
        return jnp.asarray(values, dtype=dtype)
    return np.asarray(values, dtype=dtype)


def stack_points(points, dtype):
    """Points ``(x, z)`` as an array ``(k, 2)`` of ``dtype``, as :func:`stack` (NumPy when all are concrete)."""
    if any(isinstance(v, jax.core.Tracer) or any(isinstance(c, jax.core.Tracer) for c in v) for v in points):
        return jnp.stack([jnp.stack([jnp.asarray(c, dtype=dtype) for c in v]) for v in points])
    return np.stack([np.asarray([np.asarray(c, dtype=dtype) for c in v], dtype=dtype) for v in points])


class PlanarChain(eqx.Module):
    """A planar tree of ``n`` links, ``m`` of them actuated, as the planar derivations read it.

    Physical parameters are arrays of shape ``(n,)`` (``gear``: ``(m,)``; ``gravity``: ``()``; ``attach``: ``(k, 2)``
    for the ``k`` links with an attach point of their own), NumPy where concrete; structure is static.

    Args:
        links: a non-empty sequence of :class:`Link`, parents before their children.
        gravity: gravitational acceleration [m/s^2] along -z.
        contact: the ground contact law (:class:`lagrange.PenaltyContact`) pressing the links' ``contacts`` points;
            ``None`` (the default): no contact. Given exactly when some link has contact points.
        limits: the joint limit law (:class:`lagrange.PenaltyLimits`) enforcing the links' ``range``; ``None`` (the
            default): no limits. Given exactly when some link has a range.
        dtype: the arrays' float type (default JAX's).

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

    Nothing is checked here but the parents' order and the laws: the tree it is lowered from was checked when it was
    built (:class:`lagrange.chain.Chain`, :class:`lagrange.Tree`) and its parameters by
    :func:`lagrange.model.checks.check_parameters`.
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
                 contact: PenaltyContact | None = None, limits: PenaltyLimits | None = None, dtype=None):
        links = tuple(links)
        parents = check_parents(links)
        dtype = jax.dtypes.canonicalize_dtype(float) if dtype is None else dtype
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
    def nv(self) -> int:
        """Number of velocities: ``n``."""
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


class AbstractPlanar(AbstractBackend):
    """A planar tree as the planar derivations read it: ``q`` and ``qd`` the links' coordinates and rates.

    Attributes:
        chain: the lowered tree, its concrete parameters NumPy arrays.
        derivation: the module whose functions of the methods' names (``mass_matrix(chain, q)``, ...) derive the
            equations: :mod:`lagrange.planar.unrolled` or :mod:`lagrange.planar.recursive`.
    """

    chain: PlanarChain
    euclidean: ClassVar[bool] = True
    derivation: ClassVar[ModuleType]

    def mass_matrix(self, q):
        return self.derivation.mass_matrix(self.chain, q)

    def bias_forces(self, q, qd):
        return self.derivation.bias_forces(self.chain, q, qd)

    def gravity_forces(self, q):
        return self.derivation.gravity_forces(self.chain, q)

    def forward_dynamics(self, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
        return self.derivation.forward_dynamics(self.chain, q, qd, u, implicit_damping_dt, pivots=pivots)

    def inverse_dynamics(self, q, qd, qdd):
        return self.derivation.inverse_dynamics(self.chain, q, qd, qdd)

    def energy(self, q, qd):
        return self.derivation.energy(self.chain, q, qd)

    @property
    def nq(self) -> int:
        return self.chain.n

    @property
    def nv(self) -> int:
        return self.chain.n

    @property
    def m(self) -> int:
        return self.chain.m

    def check_coordinates(self, name, q):
        pass  # hinge angles and slides: every value is a configuration

    @property
    def damping(self):
        return self.chain.damping

    state_dependent_actuation: ClassVar[bool] = False  # the lowering carries motors only

    def actuation(self, u, q=None, qd=None):
        if u is None or not self.chain.m:
            return None
        return jnp.einsum("ij,...j->...i", actuation_matrix(self.chain), clamp_controls(self.chain, u))

    def spring_forces(self, q):
        if self.chain.stiffness is None:
            return None
        return self.chain.stiffness * (q - self.chain.springref)

    def move(self, q, v, h):
        return q + h * v

    def rate(self, q, v):
        return v

    def dexpinv(self, theta, v):
        return v

    def normalize(self, q):
        return q
