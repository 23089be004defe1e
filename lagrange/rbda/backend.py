"""The general backend: any tree's equations by the rigid-body algorithms of :mod:`lagrange.rbda` (RNEA, CRBA and a
Cholesky solve), its coordinates on the joints' manifold (quaternions by the exponential map)."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from lagrange import rbda
from lagrange.backend import AbstractBackend
from lagrange.model.tree import Tree
from lagrange.rbda.forces import actuation, passive, per_dof

__all__ = ["General"]


def _arrays(*xs):
    return tuple(None if x is None else jnp.asarray(x) for x in xs)


class General(AbstractBackend):
    """A tree and the general rigid-body algorithms (:mod:`lagrange.rbda`).

    Attributes:
        tree: the tree, its concrete parameters NumPy arrays.
    """

    tree: Tree
    euclidean: ClassVar[bool] = False

    @property
    def nq(self) -> int:
        return self.tree.nq

    @property
    def nv(self) -> int:
        return self.tree.nv

    @property
    def m(self) -> int:
        return self.tree.m

    def check_coordinates(self, name, q):
        if isinstance(q, jax.core.Tracer):
            return
        for link, j in enumerate(self.tree.joints):
            if j.nq > j.nv:
                start = self.tree.qadr[link] + j.nq - 4
                quat = np.asarray(q)[..., start: start + 4]
                if not np.all(np.linalg.norm(quat, axis=-1) > 1e-12):
                    raise ValueError(f"{name}[{start}:{start + 4}] is joint {link}'s quaternion and must not be zero "
                                     f"(any non-zero length is normalised), got {quat.tolist()}")

    @property
    def damping(self):
        return per_dof(self.tree, "damping")

    def mass_matrix(self, q):
        return rbda.mass_matrix(self.tree, *_arrays(q))

    def bias_forces(self, q, qd):
        return rbda.bias_forces(self.tree, *_arrays(q, qd))

    def gravity_forces(self, q):
        return rbda.gravity_forces(self.tree, *_arrays(q))

    def forward_dynamics(self, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
        return rbda.forward_dynamics(self.tree, *_arrays(q, qd, u), implicit_damping_dt=implicit_damping_dt,
                                     pivots=pivots)

    def inverse_dynamics(self, q, qd, qdd):
        return rbda.inverse_dynamics(self.tree, *_arrays(q, qd, qdd))

    def energy(self, q, qd):
        return rbda.energy(self.tree, *_arrays(q, qd))

    @property
    def state_dependent_actuation(self) -> bool:
        return bool(self.tree.muscles) or any(mo.state_dependent for mo in self.tree.motors)

    def actuation(self, u, q=None, qd=None):
        motors = actuation(self.tree, *_arrays(u, q, qd))
        if u is None or not self.tree.muscles:
            return motors
        muscles = rbda.muscle_torques(self.tree, *_arrays(q, qd, u))
        return muscles if motors is None else motors + muscles

    def actuated_forces(self, q, qd, u=None):
        return rbda.actuated_forces(self.tree, *_arrays(q, qd, u))

    def spring_forces(self, q):
        springs = passive(self.tree, q, None)
        return None if springs is None else -springs

    def move(self, q, v, h):
        return rbda.integrate_positions(self.tree, q, v, h)

    def rate(self, q, v):
        return rbda.position_derivative(self.tree, q, v)

    def dexpinv(self, theta, v):
        return rbda.dexpinv(self.tree, theta, v)

    def normalize(self, q):
        return rbda.normalize_quaternions(self.tree, q)
