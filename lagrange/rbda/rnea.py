"""The recursive Newton-Euler algorithm on a spatial tree: inverse dynamics, bias and gravity forces.

``a_i = a_0 + sum_{k on i's path} (c_k + S_k qdd_k)`` with the base acceleration ``a_0 = (0, -g)`` (gravity as the
world accelerating upward), ``f_i = I_i a_i + v_i x* I_i v_i``, ``tau_i = S_i^T sum_{k in i's subtree} f_k``. In
world-aligned coordinates at each tree's reference point the sums along paths and over subtrees need no transform:
each is one product with the tree's 0/1 path matrix (or its transpose) over all links at once.
"""

from __future__ import annotations

import jax.numpy as jnp

from lagrange.math import spatial as al
from lagrange.rbda.kinematics import Kinematics

__all__ = ["rnea"]


def rnea(k: Kinematics, qdd=None, *, velocity: bool = True, gravity: bool = True, external=None):
    """``M qdd + C qd + T - J^T f_ext``, the rigid bodies' part of the generalized forces, ``(..., nv)``.

    Args:
        k: the kinematics (with ``qd`` when ``velocity``).
        qdd: accelerations ``(..., nv)``, or ``None`` for zero.
        velocity: include the velocity products ``C qd``.
        gravity: include gravity ``T``.
        external: spatial forces on the links ``(..., n, 6)`` (at the reference points, world-aligned), or ``None``.
    """
    dtype = k.R.dtype
    aJ = jnp.zeros(k.p.shape[:-1] + (6,), dtype)
    if velocity:
        aJ = aJ + k.c
    if qdd is not None:
        aJ = aJ + k.joint_motion(qdd)
    a = k.down(aJ)
    if gravity:
        a = a + jnp.concatenate([jnp.zeros(3, dtype), -jnp.asarray(k.tree.gravity, dtype)])
    f = al.rigid_apply(k.m, k.h, k.J, a)
    if velocity:
        f = f + al.cross_force(k.v, al.rigid_apply(k.m, k.h, k.J, k.v))
    if external is not None:
        f = f - external
    return k.project(k.up(f))
