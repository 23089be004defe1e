"""The composite-rigid-body algorithm on a spatial tree: the mass matrix.

``Ic_i = sum_{k in i's subtree} I_k`` (rigid inertias about one point add: one product with the path matrix's
transpose); ``M_ab = S_a . Ic_j S_b`` for every velocity ``a`` of a link at or above the link ``j`` of the velocity
``b`` (and symmetrically), zero where neither link is above the other; armature on the diagonal. The entries are one
batched product ``S (Ic S)^T`` over all velocities, whose entries for related pairs make ``M`` (the upper link's
velocity first; zero elsewhere).
"""

from __future__ import annotations

import jax.numpy as jnp

from lagrange.math import spatial as al
from lagrange.rbda.forces import per_dof
from lagrange.rbda.kinematics import Kinematics

__all__ = ["crba"]


def _above(k: Kinematics):
    """``above[a, b]``: velocity ``a``'s link is on the path to velocity ``b``'s (the same link included)."""
    link = k.structure.dof_link
    return k.structure.path[link][:, link].T > 0


def crba(k: Kinematics):
    """``M`` of shape ``(..., nv, nv)``, armature on the diagonal."""
    dtype = k.R.dtype
    batch = k.p.shape[:-2]
    link = k.structure.dof_link
    m = k.up(jnp.broadcast_to(jnp.asarray(k.m, dtype), batch + k.m.shape), axis=-1)
    h, J = k.up(k.h), k.up(k.J, axis=-3)
    F = al.rigid_apply(al.take(m, link, -1), al.take(h, link, -2), al.take(J, link, -3), k.S)  # Ic_j S_b
    G = jnp.einsum("...ad,...bd->...ab", k.S, F)  # S_a . Ic_{link of b} S_b, right where a's link is above b's
    above = _above(k)
    M = jnp.where(above, G, 0.0) + jnp.where(above.T & ~above, jnp.swapaxes(G, -1, -2), 0.0)
    armature = per_dof(k.tree, "armature")
    if armature is not None:
        M = M + jnp.diag(jnp.asarray(armature, dtype))
    return M
