"""What a backend is: a tree prepared for one derivation of its equations, and the quantities every derivation
gives.

:func:`lagrange.dynamics.backend` prepares a tree (its parameters checked and folded) and picks the backend, once per
public call: the planar ones (:class:`lagrange.planar.unrolled.Unrolled`, :class:`lagrange.planar.recursive.Recursive`)
for a planar tree, the general rigid-body algorithms (:class:`lagrange.rbda.backend.General`) for any other. The
public functions of :mod:`lagrange.dynamics` and :func:`lagrange.simulate` check their arguments and call these
methods, which check nothing. Shapes: ``q (*batch, nq)``, ``qd`` and ``qdd (*batch, nv)``, ``u (*batch, m)``.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx

__all__ = ["AbstractBackend"]


class AbstractBackend(eqx.Module):
    """A prepared tree and the derivation of its equations of motion ``M(q) qdd + bias(q, qd) = B u``.

    Attributes:
        euclidean: whether the coordinates are plain integrals of the velocities (``q + h qd`` moves them, ``nq =
            nv``): the planar backends'; a tree's quaternions move on their manifold instead.
    """

    euclidean: ClassVar[bool]

    @property
    @abc.abstractmethod
    def nq(self) -> int:
        """Number of coordinates."""

    @property
    @abc.abstractmethod
    def nv(self) -> int:
        """Number of velocities."""

    @property
    @abc.abstractmethod
    def m(self) -> int:
        """Number of controls."""

    @abc.abstractmethod
    def check_coordinates(self, name: str, q) -> None:
        """Raise a ``ValueError`` naming ``name`` where concrete coordinates ``q`` cannot be normalised (a zero
        quaternion); traced ones pass."""

    @property
    @abc.abstractmethod
    def damping(self):
        """The joints' damping per velocity ``(nv,)``, or ``None`` when no joint is damped."""

    @abc.abstractmethod
    def mass_matrix(self, q):
        """``M(q)``, ``(*batch, nv, nv)``."""

    @abc.abstractmethod
    def bias_forces(self, q, qd):
        """``C qd + T + D qd + K (q - q_ref) - tau_limits - J^T f_contact``, ``(*batch, nv)``."""

    @abc.abstractmethod
    def gravity_forces(self, q):
        """``T(q)``, ``(*batch, nv)``."""

    @abc.abstractmethod
    def forward_dynamics(self, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
        """``qdd`` (and with ``pivots``, where the factorisation of ``M`` failed), ``(*batch, nv)``."""

    @abc.abstractmethod
    def inverse_dynamics(self, q, qd, qdd):
        """``M qdd + bias``, ``(*batch, nv)``."""

    @abc.abstractmethod
    def energy(self, q, qd):
        """``(kinetic, potential)``, each ``(*batch,)``."""

    @property
    @abc.abstractmethod
    def state_dependent_actuation(self) -> bool:
        """Whether an actuator's force depends on its joint's position or velocity (``actuation`` then needs ``q`` and
        ``qd``)."""

    @abc.abstractmethod
    def actuation(self, u, q=None, qd=None):
        """The actuators' generalized forces, ``B u`` with ``u`` clamped into the motors' ranges (and the state's terms
        of the actuators that have them, and the muscles' ``-F dL/dq``, at ``q`` and ``qd``), ``(*batch, nv)``;
        ``None`` without control."""

    def actuated_forces(self, q, qd, u=None):
        """``actuation(u, q, qd) - bias_forces(q, qd)``, the right-hand side of ``M qdd = tau - bias``,
        ``(*batch, nv)`` (a backend may compute both from one kinematics)."""
        tau = None if u is None else self.actuation(u, q, qd)
        bias = self.bias_forces(q, qd)
        return -bias if tau is None else tau - bias

    @abc.abstractmethod
    def spring_forces(self, q):
        """The joint springs' ``K (q - q_ref)``, ``(*batch, nv)``; ``None`` without springs."""

    @abc.abstractmethod
    def move(self, q, v, h):
        """``q`` moved by the velocities ``v`` for ``h`` seconds."""

    @abc.abstractmethod
    def rate(self, q, v):
        """``dq/dt`` at velocities ``v``."""

    @abc.abstractmethod
    def dexpinv(self, theta, v):
        """The velocities ``v`` as the rate of the tangent increment ``theta`` (the identity where ``euclidean``)."""

    @abc.abstractmethod
    def normalize(self, q):
        """``q`` with its quaternions of unit length (as it is where ``euclidean``)."""
