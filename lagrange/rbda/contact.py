"""Ground contact of a spatial tree: DFlex's penalty law at the bodies' contact points, as spatial forces on the links.

Each point ``(x, y, z, radius)`` of a body (:attr:`lagrange.model.tree.Body.contacts`, in the body's frame) has its
lowest spot ``s = c - radius e_z`` (``c`` the point in the world); below the level ground ``z = ground`` at depth
``d = ground - s_z > 0`` it receives, at ``s``, the force of :meth:`lagrange.PenaltyContact.forces_3d`: the normal
``ke d + kd d max(-vn, 0)`` along ``+z`` and the friction ``-(vt / |vt|) min(kf |vt|, mu ke d)`` along the ground, with
``vn`` and ``vt`` the normal and tangential parts of the material velocity at ``s``. The generalized force is
``J_s^T f``: the force enters the recursive Newton-Euler algorithm as an external spatial force ``(s x f, f)`` on the
point's link, at the tree's reference point.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.math import spatial as al
from lagrange.rbda.kinematics import Kinematics, body_frames_in_links
from lagrange.model.tree import Tree

__all__ = ["contact_energy", "contact_spots", "contact_wrenches"]


def _points(tree: Tree, structure):
    """``(links (k,), points (k, 3), radii (k,))``: every contact point in its link's frame (a body welded below a
    link's body carried into that link's frame), leaving out bodies welded to the world (they cannot move)."""
    links, points, radii = [], [], []
    for b, (R, p) in body_frames_in_links(structure).items():
        for x, y, z, r in tree.bodies[b].contacts:
            links.append(structure.body_link[b])
            points.append(np.asarray(p) + np.asarray(R) @ np.array([x, y, z]))
            radii.append(r)
    return np.array(links, int), np.array(points).reshape(-1, 3), np.array(radii)


def contact_spots(k: Kinematics):
    """The contact points' lowest spots: ``(links, s, o_z)`` with ``s (..., k, 3)`` relative to the reference point
    of each point's tree and ``o_z (..., k)`` that point's height, so that a spot's height is ``o_z + s_z``."""
    links, points, radii = _points(k.tree, k.structure)
    dtype = k.R.dtype
    R, p = al.take(k.R, links, -3), al.take(k.p, links, -2)
    s = p + al.matvec(R, jnp.asarray(points, dtype)) - jnp.asarray(radii, dtype)[:, None] * jnp.asarray([0, 0, 1.0],
                                                                                                         dtype)
    return links, s, al.take(k.o, links, -2)[..., 2]


def contact_wrenches(k: Kinematics):
    """The contact forces as spatial forces on the links ``(..., n, 6)`` (world-aligned, at the reference points):
    the ``external`` argument of :func:`~lagrange.rbda.rnea.rnea`."""
    law = k.tree.contact
    links, s, oz = contact_spots(k)
    v = al.take(k.v, links, -2)
    vel = v[..., 3:] + al.cross(v[..., :3], s)  # the material velocity at the spot
    depth = law.ground.astype(s.dtype) - (oz + s[..., 2])
    fn, ft = law.forces_3d(depth, vel[..., 2], vel[..., :2])
    f = jnp.concatenate([ft, fn[..., None]], axis=-1)
    wrench = jnp.concatenate([al.cross(s, f), f], axis=-1)  # (s x f, f) per point
    E = (np.arange(k.structure.n)[:, None] == links[None, :]).astype(float)  # link <- point
    return jnp.einsum("...kc,ik->...ic", wrench, jnp.asarray(E, s.dtype))


def contact_energy(k: Kinematics):
    """The contact springs' ``1/2 ke d^2`` summed over the points, ``(...)``."""
    law = k.tree.contact
    _, s, oz = contact_spots(k)
    return jnp.sum(law.energy(law.ground.astype(s.dtype) - (oz + s[..., 2])), axis=-1)
