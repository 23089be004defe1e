"""The planar backends: a planar tree lowered to a :class:`~lagrange.planar.model.PlanarChain`
(:func:`~lagrange.planar.lower.lower`), its equations by the unrolled derivation (:class:`Unrolled`, chains of fewer
than ``RECURSIVE_MIN`` links) or by the recursive algorithms (:class:`Recursive`)."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from lagrange.backend import AbstractBackend
from lagrange.forces import actuation_matrix, clamp_controls
from lagrange.planar import recursive, unrolled
from lagrange.planar.model import PlanarChain

__all__ = ["AbstractPlanar", "Recursive", "Unrolled"]


class AbstractPlanar(AbstractBackend):
    """A planar tree as the planar derivations read it: ``q`` and ``qd`` the links' coordinates and rates.

    Attributes:
        chain: the lowered tree, its concrete parameters NumPy arrays.
    """

    chain: PlanarChain
    euclidean: ClassVar[bool] = True

    @property
    def nq(self) -> int:
        return self.chain.n

    @property
    def nv(self) -> int:
        return self.chain.n

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


class Unrolled(AbstractPlanar):
    """The unrolled relative-angle derivation (:mod:`lagrange.planar.unrolled`): every entry written out, constants
    folded while tracing; the closed form a person writes by hand for a short chain."""

    def mass_matrix(self, q):
        return unrolled.mass_matrix(self.chain, q)

    def bias_forces(self, q, qd):
        return unrolled.bias_forces(self.chain, q, qd)

    def gravity_forces(self, q):
        return unrolled.gravity_forces(self.chain, q)

    def forward_dynamics(self, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
        return unrolled.forward_dynamics(self.chain, q, qd, u, implicit_damping_dt, pivots=pivots)

    def inverse_dynamics(self, q, qd, qdd):
        return jnp.einsum("...ij,...j->...i", self.mass_matrix(q), qdd) + self.bias_forces(q, qd)

    def energy(self, q, qd):
        return unrolled.energy(self.chain, q, qd)


class Recursive(AbstractPlanar):
    """Featherstone's recursive algorithms on planar spatial vectors (:mod:`lagrange.planar.recursive`): ABA, RNEA
    and CRBA as scans over the links, O(n) work."""

    def mass_matrix(self, q):
        return recursive.mass_matrix(self.chain, q)

    def bias_forces(self, q, qd):
        return recursive.bias_forces(self.chain, q, qd)

    def gravity_forces(self, q):
        return recursive.gravity_forces(self.chain, q)

    def forward_dynamics(self, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
        return recursive.forward_dynamics(self.chain, q, qd, u, implicit_damping_dt, pivots=pivots)

    def inverse_dynamics(self, q, qd, qdd):
        return recursive.inverse_dynamics(self.chain, q, qd, qdd)

    def energy(self, q, qd):
        return recursive.energy(self.chain, q, qd)
