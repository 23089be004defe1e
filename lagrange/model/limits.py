"""Joint limits by penalty forces: a joint outside its range ``[lower, upper]`` (``Link(range=...)``) is pushed back.

Outside the range the joint gets the generalized force ``ke (bound - q) - kd qd`` (``bound`` the one it passed);
inside it gets nothing. The spring's potential energy is ``1/2 ke (q - bound)^2``. Gradients are finite everywhere:
the force is piecewise linear, and exactly on a bound it is the inside (zero) one. DFlex applies its limit damping at
all times (``jcalc_tau`` in NVlabs/DiffRL at commit 6b8d695, ``dflex/dflex/sim.py``; its comment says otherwise); a task
that must reproduce DFlex adds that damping to the joints' ``damping`` instead and gives ``kd = 0`` here.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from lagrange.model.contact import scalar_parameter


class PenaltyLimits(eqx.Module):
    """Joint limits by penalty forces, one law for every limited joint of a chain (the law: the module docstring).

    Args:
        ke: limit stiffness [N m/rad or N/m], > 0.
        kd: limit damping [N m s/rad or N s/m], >= 0, applied outside the range only.

    Attributes:
        ke: limit stiffness [N m/rad or N/m], a 0-d array (differentiable).
        kd: limit damping [N m s/rad or N s/m], a 0-d array (differentiable).
    """

    ke: Float[Array, ""]
    kd: Float[Array, ""]

    def __init__(self, ke: Float[ArrayLike, ""], kd: Float[ArrayLike, ""] = 0.0):
        self.ke = scalar_parameter("PenaltyLimits", "ke", ke, positive=True)
        self.kd = scalar_parameter("PenaltyLimits", "kd", kd)

    def forces(self, q, qd, lower, upper):
        """The limits' generalized forces, by the law of the module docstring.

        Args:
            q: joint coordinates [rad or m]; any shape.
            qd: joint velocities [rad/s or m/s]; broadcast against ``q``.
            lower: the ranges' lower bounds [rad or m]; broadcast against ``q``.
            upper: the ranges' upper bounds [rad or m]; broadcast against ``q``.

        Returns:
            ``ke (bound - q) - kd qd`` outside the range, 0 inside (and on a bound) [N m or N], of the broadcast
            shape.
        """
        below = jnp.where(q < lower, q - lower, 0.0)
        above = jnp.where(q > upper, q - upper, 0.0)
        outside = (q < lower) | (q > upper)
        return -self.ke * (below + above) - jnp.where(outside, self.kd * qd, 0.0)

    def energy(self, q, lower, upper):
        """The limit springs' potential energy.

        Args:
            q: joint coordinates [rad or m]; any shape.
            lower: the ranges' lower bounds [rad or m]; broadcast against ``q``.
            upper: the ranges' upper bounds [rad or m]; broadcast against ``q``.

        Returns:
            ``1/2 ke (q - bound)^2`` [J] outside the range, 0 inside, elementwise.
        """
        v = jnp.where(q < lower, q - lower, 0.0) + jnp.where(q > upper, q - upper, 0.0)
        return 0.5 * self.ke * v * v
