"""Where a tree's bodies are: their origins, centres of mass, tips and contact points in the world at coordinates
``q``, for every tree alike (the general kinematics of :mod:`lagrange.rbda`; what a plot or a reward reads, not
what the dynamics run on).

A :class:`lagrange.chain.Chain` lives in the world's x-z plane, so its rows are ``(x, 0, z)``: ``[..., ::2]`` are the
planar coordinates.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from lagrange import rbda
from lagrange.model.checks import check_shapes
from lagrange.model.tree import Tree, check_tree

__all__ = ["com_positions", "contact_point_positions", "muscle_lengths", "positions", "tip_positions"]


def _q(tree: Tree, q):
    check_tree(tree)
    check_shapes(tree, q=q)
    return jnp.asarray(q)


def positions(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch bodies 3"]:
    """Every body's origin in the world [m] (a chain's links: their joints), shape ``(*batch, bodies, 3)``, at
    coordinates ``q`` of shape ``(*batch, nq)``."""
    return rbda.positions(tree, _q(tree, q))


def com_positions(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch bodies 3"]:
    """Every body's centre of mass in the world [m], shape ``(*batch, bodies, 3)``."""
    return rbda.com_positions(tree, _q(tree, q))


def tip_positions(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch bodies 3"]:
    """Every body's ``tip`` in the world [m] (a chain's links: their far ends), its origin for a body without one,
    shape ``(*batch, bodies, 3)``; with :func:`positions`, what a drawing of the tree needs."""
    return rbda.tip_positions(tree, _q(tree, q))


def contact_point_positions(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch k 3"]:
    """The bodies' contact points (their centres, not lowered by the radius) in the world [m], bodies in order and
    each body's points in order, shape ``(*batch, k, 3)``; ``k = 0`` for a tree without contact points."""
    return rbda.contact_point_positions(tree, _q(tree, q))


def muscle_lengths(tree: Tree, q: Float[ArrayLike, "*batch nq"]) -> Float[Array, "*batch muscles"]:
    """Every muscle's path length ``L(q)`` [m] (:class:`lagrange.Muscle`: the polyline through its waypoints), shape
    ``(*batch, muscles)``; its generalized force is ``-F dL/dq``."""
    return rbda.muscle_lengths(tree, _q(tree, q))
