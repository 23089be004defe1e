"""Contact and limit forces on the per-link arrays of the recursive algorithms.

:func:`contact_wrenches` gives each link the spatial force ``(moment about p_i, Fx, Fz)`` of its contact points'
penalty forces (:class:`lagrange.PenaltyContact`), which ABA and RNEA take off the links' bias forces
``v x* I v``; :func:`limit_torques` the joints' penalty limit torques (:class:`lagrange.PenaltyLimits`). Only the links
with contact points and the joints with a range compute anything.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.planar.model import PlanarChain
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.recursive.tree import param


def contact_spots(chain: PlanarChain, k: LinkKinematics):
    """Where each contact point's lowest spot is.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        k: the links' kinematics (:class:`~lagrange.planar.recursive.kinematics.LinkKinematics`).

    Returns:
        ``(idx, sx, sz, rx, rz)``: each point's link index (``(points,)``), its lowest spot ``s`` (x, z) [m] and the
        offset ``s - p_i`` from its link's joint [m], each ``(points, *batch)``.
    """
    idx = np.asarray(chain.contact_links)
    tree = k.topology
    px, pz = tree.path_sum(k.rx), tree.path_sum(k.rz)
    off = np.asarray(chain.frame_offsets())[idx]
    co, so = (np.cos(off), np.sin(off))
    nb = k.sin.ndim - 1
    x, z, r = (param(chain.contact_points[:, c], nb) for c in range(3))
    sin, cos = k.sin[idx], k.cos[idx]
    # the link frame's angle a = phi + off: cos a, sin a; a point (x, z) of the frame is at p + x e(a) - z d(a)
    ca = cos * param(jnp.asarray(co, sin.dtype), nb) - sin * param(jnp.asarray(so, sin.dtype), nb)
    sa = sin * param(jnp.asarray(co, sin.dtype), nb) + cos * param(jnp.asarray(so, sin.dtype), nb)
    rx = x * ca - z * sa
    rz = x * sa + z * ca - r  # lowered by the radius
    return idx, px[idx] + rx, pz[idx] + rz, rx, rz


def contact_wrenches(chain: PlanarChain, k: LinkKinematics):
    """The contact forces on each link, as a spatial force about its joint.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        k: the links' kinematics (:class:`~lagrange.planar.recursive.kinematics.LinkKinematics` with velocities).

    Returns:
        ``(t, Fx, Fz)``, each ``(n, *batch)``: the moment about ``p_i`` [N m] and the force [N] of the link's contact
        points' penalty forces; ``None`` without contact.
    """
    if chain.contact is None:
        return None
    idx, sx, sz, rx, rz = contact_spots(chain, k)
    # the material velocity at the spot: v_i + w_i perp(s - p_i), perp(x, z) = (-z, x)
    w = k.w[idx]
    vx, vz = k.vx[idx] - w * rz, k.vz[idx] + w * rx
    fn, ft = chain.contact.forces(chain.contact.ground - sz, vz, vx)
    t = rx * fn - rz * ft  # cross(s - p_i, (ft, fn))
    zeros = jnp.zeros(k.sin.shape, k.sin.dtype)
    return tuple(zeros.at[idx].add(v) for v in (t, ft, fn))


def contact_energy(chain: PlanarChain, k: LinkKinematics):
    """The contact springs' potential energy.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        k: the links' kinematics (:class:`~lagrange.planar.recursive.kinematics.LinkKinematics`).

    Returns:
        ``sum_points 1/2 ke d^2`` [J], shape ``batch``; ``None`` without contact.
    """
    if chain.contact is None:
        return None
    _, _, sz, _, _ = contact_spots(chain, k)
    return jnp.sum(chain.contact.energy(chain.contact.ground - sz), axis=0)


def limit_torques(chain: PlanarChain, q, qd):
    """The limits' generalized forces.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        q: joint coordinates [rad or m], links first ``(n, *batch)``.
        qd: joint velocities [rad/s or m/s], links first ``(n, *batch)``.

    Returns:
        ``tau_limits`` [N m or N], shape ``(n, *batch)`` (zero on the unlimited joints); ``None`` without limits.
    """
    if chain.limits is None:
        return None
    idx = np.asarray(chain.limited)
    nb = q.ndim - 1
    lo, hi = param(chain.ranges[:, 0], nb), param(chain.ranges[:, 1], nb)
    tau = chain.limits.forces(q[idx], qd[idx], lo, hi, axis=0)
    return jnp.zeros(q.shape, tau.dtype).at[idx].add(tau)


def limit_energy(chain: PlanarChain, q):
    """The limit springs' potential energy.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        q: joint coordinates [rad or m], links first ``(n, *batch)``.

    Returns:
        ``sum_joints 1/2 ke (q - bound)^2`` [J] outside the ranges, shape ``batch``; ``None`` without limits.
    """
    if chain.limits is None:
        return None
    idx = np.asarray(chain.limited)
    nb = q.ndim - 1
    lo, hi = param(chain.ranges[:, 0], nb), param(chain.ranges[:, 1], nb)
    return jnp.sum(chain.limits.energy(q[idx], lo, hi, axis=0), axis=0)
