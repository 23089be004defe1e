"""The composite-rigid-body algorithm: the mass matrix in O(n^2).

Composite inertias ``Ic_i = I_i + X_{i+1}^T Ic_{i+1} X_{i+1}`` (cumulative sums of mass, first and second moments
inward), then ``M_ij = S_j . X_{j<-i}^T Ic_i S_i`` for ``j <= i``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange import _scalar as s
from lagrange.chain import Chain
from lagrange.recursive.kinematics import LinkKinematics
from lagrange.recursive.tree import cumsum, next_link, param, prepare, rcumsum


def mass_matrix(chain: Chain, q):
    """``M(q)`` by the composite-rigid-body algorithm, shape (..., n, n); O(n^2) work."""
    batch, _, q, _ = prepare(chain, q, None)
    k = LinkKinematics(chain, q, None, len(batch))
    m = jnp.broadcast_to(k.m, q.shape)
    rx, rz = next_link(k.rx), next_link(k.rz)
    mc = rcumsum(m)  # composite mass of links >= i
    mn = next_link(mc)
    hx = rcumsum(k.hx + mn * rx)  # composite first moment about p_i
    hz = rcumsum(k.hz + mn * rz)
    J = rcumsum(k.J + 2 * (rx * next_link(hx) + rz * next_link(hz)) + mn * (rx * rx + rz * rz))
    S = k.S
    # F_i = Ic_i S_i at p_i
    Ft = s.add(s.add(s.mul(J, S[0]), s.mul(-hz, S[1])), s.mul(hx, S[2]))
    Fx = s.add(s.mul(-hz, S[0]), s.mul(mc, S[1]))
    Fz = s.add(s.mul(hx, S[0]), s.mul(mc, S[2]))
    Ft, Fx, Fz = (jnp.broadcast_to(x, q.shape) for x in (Ft, Fx, Fz))
    px, pz = cumsum(k.rx), cumsum(k.rz)
    # M_ij (j <= i) = S_j . (F_i moved from p_i to p_j): moment Ft_i + cross(p_i - p_j, F_i)
    dx, dz = px[:, None] - px[None, :], pz[:, None] - pz[None, :]  # [i, j]
    Mt = Ft[:, None] + dx * Fz[:, None] - dz * Fx[:, None]
    Mij = s.add(s.add(s.mul(_col(S[0]), Mt), s.mul(_col(S[1]), Fx[:, None])), s.mul(_col(S[2]), Fz[:, None]))
    Mij = jnp.broadcast_to(Mij, dx.shape)
    lower = np.tril(np.ones((chain.n, chain.n), bool)).reshape((chain.n, chain.n) + (1,) * len(batch))
    M = jnp.where(lower, Mij, jnp.swapaxes(Mij, 0, 1))
    if chain.armature is not None:
        eye = np.eye(chain.n).reshape(M.shape[:2] + (1,) * len(batch))
        M = M + eye * param(chain.armature, len(batch))[:, None]
    return jnp.moveaxis(M, (0, 1), (-2, -1))


def _col(x):
    """A per-link (n, *batch) array as the j index of an [i, j] array; constants pass through."""
    return x if s.is_const(x) else x[None, :]
