"""The composite-rigid-body algorithm: the mass matrix in O(n^2).

Composite inertias ``Ic_i = I_i + sum_{c a child of i} X_c^T Ic_c X_c`` (sums of mass, first and second moments over
each link's subtree), then ``M_ij = S_j . X_{j<-i}^T Ic_i S_i`` for ``j`` on the path from the world to ``i``, and zero
between links on different branches.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.math import scalar as s
from lagrange.planar.model import PlanarChain
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.recursive.tree import next_link, param, prepare, rcumsum


def mass_matrix(chain: PlanarChain, q):
    """The mass matrix ``M(q)`` by the composite-rigid-body algorithm, in O(n^2).

    Arguments and result as :func:`lagrange.dynamics.mass_matrix`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    batch, _, q, _ = prepare(chain, q, None)
    k = LinkKinematics(chain, q, None, len(batch))
    tree = k.topology
    m = jnp.broadcast_to(k.m, q.shape)
    mc = tree.subtree_sum(m)  # composite mass of link i's subtree
    # composite first and second moments about p_i: each child's subtree moved by its offset r_c
    if tree.serial:  # the child is the next link
        rx, rz, mn = next_link(k.rx), next_link(k.rz), next_link(mc)
        hx = rcumsum(k.hx + mn * rx)
        hz = rcumsum(k.hz + mn * rz)
        J = rcumsum(k.J + 2 * (rx * next_link(hx) + rz * next_link(hz)) + mn * (rx * rx + rz * rz))
    else:
        hx = tree.subtree_sum(k.hx + tree.children_sum(mc * k.rx))
        hz = tree.subtree_sum(k.hz + tree.children_sum(mc * k.rz))
        J = tree.subtree_sum(k.J + tree.children_sum(2 * (k.rx * hx + k.rz * hz) + mc * (k.rx * k.rx + k.rz * k.rz)))
    S = k.S
    # F_i = Ic_i S_i at p_i
    Ft = s.add(s.add(s.mul(J, S[0]), s.mul(-hz, S[1])), s.mul(hx, S[2]))
    Fx = s.add(s.mul(-hz, S[0]), s.mul(mc, S[1]))
    Fz = s.add(s.mul(hx, S[0]), s.mul(mc, S[2]))
    Ft, Fx, Fz = (jnp.broadcast_to(x, q.shape) for x in (Ft, Fx, Fz))
    px, pz = tree.path_sum(k.rx), tree.path_sum(k.rz)
    # M_ij (j on i's path) = S_j . (F_i moved from p_i to p_j): moment Ft_i + cross(p_i - p_j, F_i)
    dx, dz = px[:, None] - px[None, :], pz[:, None] - pz[None, :]  # [i, j]
    Mt = Ft[:, None] + dx * Fz[:, None] - dz * Fx[:, None]
    Mij = s.add(s.add(s.mul(_col(S[0]), Mt), s.mul(_col(S[1]), Fx[:, None])), s.mul(_col(S[2]), Fz[:, None]))
    Mij = jnp.broadcast_to(Mij, dx.shape)
    shape = (chain.n, chain.n) + (1,) * len(batch)
    if tree.serial:
        lower = np.tril(np.ones((chain.n, chain.n), bool)).reshape(shape)
        M = jnp.where(lower, Mij, jnp.swapaxes(Mij, 0, 1))
    else:  # zero between links on different branches
        on_path = tree.path.reshape(shape)
        M = jnp.where(on_path, Mij, jnp.where(on_path.swapaxes(0, 1), jnp.swapaxes(Mij, 0, 1), 0.0))
    if chain.armature is not None:
        eye = np.eye(chain.n).reshape(M.shape[:2] + (1,) * len(batch))
        M = M + eye * param(chain.armature, len(batch))[:, None]
    return jnp.moveaxis(M, (0, 1), (-2, -1))


def _col(x):
    """A per-link (n, *batch) array as the j index of an [i, j] array; constants pass through."""
    return x if s.is_const(x) else x[None, :]
