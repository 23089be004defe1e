"""The recursive algorithms behind :mod:`lagrange.dynamics` for chains of ``RECURSIVE_MIN`` or more links.

Call :mod:`lagrange.dynamics` (``forward_dynamics``, ``mass_matrix``, ...): it checks the arguments and picks these or
the unrolled derivation (:mod:`lagrange.planar.unrolled`) by the chain's size. One module per algorithm:
:mod:`~lagrange.planar.recursive.kinematics` (the links' angles, offsets and velocities, one scan outward),
:mod:`~lagrange.planar.recursive.rnea` (bias, gravity and inverse dynamics), :mod:`~lagrange.planar.recursive.crba`
(the mass matrix), :mod:`~lagrange.planar.recursive.aba` (forward dynamics),
:mod:`~lagrange.planar.recursive.energies`, and
:mod:`~lagrange.planar.recursive.contact` (the contact and limit forces), on the per-link arrays and scans of
:mod:`~lagrange.planar.recursive.tree`.

The unrolled derivation writes out every entry of ``M`` and solves ``M qdd = rhs`` by elimination, so its work and its
compiled program grow like n^3. Here the same equations are evaluated by Featherstone's recursive algorithms (ABA,
RNEA and CRBA) on planar spatial vectors, with every per-link quantity held in arrays whose leading axis runs over the
links: the compiled program has the same size for every n and the work is O(n) (forward dynamics, bias and gravity
forces) or O(n^2) (the mass matrix).

Planar spatial algebra. A *motion* ``(w, vx, vz)`` is an angular velocity ``w = dphi/dt`` and
the velocity of the body point at a reference point; a *force* ``(t, Fx, Fz)`` is a moment about
that point and a force. With ``perp(x, z) = (-z, x)`` (so ``d/dt d(phi) = w perp(d(phi))``) and
``cross(a, b) = a_x b_z - a_z b_x``:

- moving the reference point by ``r`` (``p_new = p_old + r``): a motion becomes
  ``(w, v + w perp(r))`` (the matrix ``X(r)``), a force given at ``p_new`` becomes
  ``(t + perp(r).F, F)`` at ``p_old`` (``X(r)^T``);
- ``m1 x m2 = (0, w1 perp(v2) - w2 perp(v1))`` and ``m x* f = (cross(v, F), w perp(F))``;
- a body of mass ``m``, centre of mass at ``c`` from the reference point and inertia ``I``
  about it has the spatial inertia ``[[I + m|c|^2, m perp(c)^T], [m perp(c), m 1]]``.

Body i's reference point is its joint origin ``p_i`` and every frame keeps the world's axes, so
``X_i = X(r_i)`` with ``r_i = p_i - p_parent(i)`` (the attach point in the world's axes, plus
``q_i e(phi_parent + axis_i)`` for a prismatic joint), and the joint's motion subspace is ``S_i = (sense_i, 0, 0)``
(revolute) or ``(0, e(phi_parent + axis_i))`` (prismatic). Gravity enters as the base acceleration
``a_0 = (0, 0, g)``. With ``parent(i)`` the link's parent (the world for a link of the world):

- kinematics: ``v_i = X_i v_parent(i) + S_i qd_i`` and ``c_i = v_i x S_i qd_i``, with the link angles, their
  sines and cosines and the joint offsets ``r_i``: one ``jax.lax.scan`` outward over the links;
- RNEA: ``a_i = X_i a_parent(i) + S_i qdd_i + c_i``, ``f_i = I_i a_i + v_i x* I_i v_i``,
  ``tau_i = S_i . sum_{k in i's subtree} X_{i<-k}^T f_k`` (sums along paths and over subtrees: cumulative sums on a
  serial chain);
- CRBA: composite inertias ``Ic_i = I_i + sum_{c a child of i} X_c^T Ic_c X_c``, ``M_ij = S_j . X_{j<-i}^T Ic_i S_i``
  for ``j`` on ``i``'s path (zero where neither is on the other's path);
- ABA: inward, ``IA_i = I_i + sum_{c a child of i} X_c^T Ia_c X_c``, ``pA_i = v_i x* I_i v_i +
  sum_c X_c^T pa_c``, ``U_i = IA_i S_i``, ``D_i = S_i . U_i + armature_i``,
  ``u_i = tau_i - S_i . pA_i``, ``Ia_i = IA_i - U_i U_i^T / D_i``,
  ``pa_i = pA_i + Ia_i c_i + U_i u_i / D_i``; outward, ``a'_i = X_i a_parent(i) + c_i``,
  ``qdd_i = (u_i - U_i . a'_i) / D_i``, ``a_i = a'_i + S_i qdd_i``. The two passes are
  ``jax.lax.scan`` over the links (:class:`~lagrange.planar.recursive.tree.Topology`: on a tree a link's carry comes
  from its parent, or goes to it, through a few slots), each step's inputs and outputs separate arrays of the
  batch's shape. Armature and an implicit-damping term ``h damping_i`` add to ``D_i``, which is adding them to ``M_ii``.

Contact forces enter as external spatial forces on the links (:mod:`~lagrange.planar.recursive.contact`), the joints'
springs, dampers and limits as generalized forces. Functions take ``q``/``qd``/``u`` with any leading batch dimensions
(broadcast against each other) and return the same quantities as :mod:`lagrange.dynamics`.
"""

import sys
from types import ModuleType
from typing import ClassVar

from lagrange.planar.model import AbstractPlanar
from lagrange.planar.recursive.aba import forward_dynamics
from lagrange.planar.recursive.crba import mass_matrix
from lagrange.planar.recursive.energies import energy
from lagrange.planar.recursive.rnea import bias_forces, gravity_forces, inverse_dynamics

__all__ = ["Recursive", "bias_forces", "energy", "forward_dynamics", "gravity_forces", "inverse_dynamics",
           "mass_matrix"]


class Recursive(AbstractPlanar):
    """Featherstone's recursive algorithms on planar spatial vectors (this package): ABA, RNEA and CRBA as scans over
    the links, O(n) work."""

    derivation: ClassVar[ModuleType] = sys.modules[__name__]
