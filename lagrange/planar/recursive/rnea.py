"""The recursive Newton-Euler algorithm: bias, gravity and inverse dynamics forces in O(n).

``a_i = X_i a_{i-1} + S_i qdd_i + c_i``, ``f_i = I_i a_i + v_i x* I_i v_i``, ``tau_i = S_i . sum_{k in i's subtree}
X_{i<-k}^T f_k``, with gravity as the base acceleration ``a_0 = (0, 0, g)``; the accelerations are sums along each
link's path from the world and the forces sums over each link's subtree (cumulative sums on a serial chain,
:class:`~lagrange.planar.recursive.tree.Topology`), on the per-link arrays of
:class:`~lagrange.planar.recursive.kinematics.LinkKinematics`.
"""

from __future__ import annotations

import jax.numpy as jnp

from lagrange.math import scalar as s
from lagrange.planar.model import PlanarChain
from lagrange.planar.recursive.contact import contact_wrenches, limit_torques
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.recursive.tree import links_first, links_last, param, prepare


def damping_force(chain: PlanarChain, qd):
    """The joints' damping forces.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        qd: joint velocities [rad/s or m/s], links first ``(n, *batch)``.

    Returns:
        ``D qd`` [N m or N], shape ``(n, *batch)``; ``None`` for an undamped chain.
    """
    return None if chain.damping is None else param(chain.damping, qd.ndim - 1) * qd


def spring_force(chain: PlanarChain, q):
    """The joint springs' forces.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        q: joint coordinates [rad or m], links first ``(n, *batch)``.

    Returns:
        ``K (q - q_ref)`` [N m or N], shape ``(n, *batch)``; ``None`` for a chain without joint springs.
    """
    if chain.stiffness is None:
        return None
    nb = q.ndim - 1
    return param(chain.stiffness, nb) * (q - param(chain.springref, nb))


def passive_force(chain: PlanarChain, q, qd):
    """The joints' dampers, springs and limits, as one generalized force on the bias side.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        q: joint coordinates [rad or m], links first ``(n, *batch)``.
        qd: joint velocities [rad/s or m/s], links first ``(n, *batch)``.

    Returns:
        ``D qd + K (q - q_ref) - tau_limits`` [N m or N], shape ``(n, *batch)``; ``None`` without any of them.
    """
    out = damping_force(chain, qd)
    springs = spring_force(chain, q)
    if springs is not None:
        out = springs if out is None else out + springs
    limits = limit_torques(chain, q, qd)
    if limits is not None:
        out = -limits if out is None else out - limits
    return out


def _rnea(chain: PlanarChain, k: LinkKinematics, qdd, gravity: bool):
    """``S_i . (sum_{k in i's subtree} X^T f_k)`` for ``f = I a + v x* I v``, shape (n, *batch)."""
    g = chain.gravity if (gravity and chain.gravity is not None) else 0.0
    tree = k.topology
    S = k.S
    cx = 0.0 if k.cx is None else k.cx
    cz = 0.0 if k.cz is None else k.cz
    if qdd is None:  # a_i = a_0 + sum_{k on i's path} c_k (c has no angular part)
        al = 0.0
        ax = 0.0 if s.is_const(cx) else tree.path_sum(cx)
        az = 0.0 if s.is_const(cz) else tree.path_sum(cz)
    else:
        al = tree.path_sum(s.mul(S[0], qdd))
        ap = tree.parent_value(al, 0.0)
        ax = tree.path_sum(s.add(s.add(s.mul(s.neg(ap), k.rz), s.mul(S[1], qdd)), cx))
        az = tree.path_sum(s.add(s.add(s.mul(ap, k.rx), s.mul(S[2], qdd)), cz))
    az = s.add(az, g)
    t, Fx, Fz = k.momentum(al, ax, az)
    if k.pA is not None:
        t, Fx, Fz = t + k.pA[0], Fx + k.pA[1], Fz + k.pA[2]
        external = contact_wrenches(chain, k)
        if external is not None:
            t, Fx, Fz = t - external[0], Fx - external[1], Fz - external[2]
    like = k.sin
    t, Fx, Fz = (jnp.broadcast_to(x, like.shape) for x in (t, Fx, Fz))
    Fx, Fz = tree.subtree_sum(Fx), tree.subtree_sum(Fz)
    # moments about p_i: t_i + perp(r_c) . Ftot_c for each child c + (the same for the links below)
    t = tree.subtree_sum(t - tree.children_sum(k.rz * Fx) + tree.children_sum(k.rx * Fz))
    return s.add(s.add(s.mul(S[0], t), s.mul(S[1], Fx)), s.mul(S[2], Fz))


def bias_forces(chain: PlanarChain, q, qd):
    """The bias forces by RNEA at ``qdd = 0``, in O(n).

    Arguments and result as :func:`lagrange.dynamics.bias_forces`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    batch, _, q, qd = prepare(chain, q, qd)
    k = LinkKinematics(chain, q, qd, len(batch))
    f = _rnea(chain, k, None, gravity=True)
    passive = passive_force(chain, q, qd)
    if passive is not None:
        f = f + passive
    return links_last(f)


def gravity_forces(chain: PlanarChain, q):
    """The generalized gravity forces by RNEA at rest, in O(n).

    Arguments and result as :func:`lagrange.dynamics.gravity_forces`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    batch, _, q, _ = prepare(chain, q, None)
    if chain.gravity is None:
        return jnp.zeros(batch + (chain.n,), q.dtype)
    return links_last(_rnea(chain, LinkKinematics(chain, q, None, len(batch)), None, gravity=True))


def inverse_dynamics(chain: PlanarChain, q, qd, qdd):
    """The generalized forces that produce ``qdd``, by RNEA, in O(n).

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`, its concrete parameters as NumPy arrays (the lowering
            folds them).
        q: joint coordinates [rad or m], shape ``(*batch, n)``.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.
        qdd: joint accelerations [rad/s^2 or m/s^2], shape ``(*batch, n)``.

    Returns:
        ``M qdd`` plus the bias forces, shape ``(*batch, n)`` [N m or N].
    """
    batch, dtype, q, qd = prepare(chain, q, qd, qdd)
    qdd = links_first(qdd.astype(dtype), batch)
    k = LinkKinematics(chain, q, qd, len(batch))
    f = _rnea(chain, k, qdd, gravity=True)
    passive = passive_force(chain, q, qd)
    if passive is not None:
        f = f + passive
    if chain.armature is not None:
        f = f + param(chain.armature, len(batch)) * qdd
    return links_last(f)
