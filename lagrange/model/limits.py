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

import jax
import numpy as np

from lagrange.model.contact import scalar_parameter


def _parameter(name: str, value, positive: bool):
    """A scalar, or one value per limited joint (a 1-d array), checked as :func:`scalar_parameter` checks a scalar."""
    if isinstance(value, jax.core.Tracer) or np.ndim(value) == 0 or isinstance(value, (bool, str)) or value is None:
        return scalar_parameter("PenaltyLimits", name, value, positive=positive)
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(f"PenaltyLimits.{name} must be a real number or one per limited joint, got {value!r}") \
            from err
    if v.ndim != 1 or not np.all(np.isfinite(v)) or np.any(v <= 0 if positive else v < 0):
        raise ValueError(f"PenaltyLimits.{name} must be a finite number {'> 0' if positive else '>= 0'} or a 1-d "
                         f"array of them (one per limited joint), got {v.tolist()}")
    return jax.device_put(v.astype(jax.dtypes.canonicalize_dtype(float)))


class PenaltyLimits(eqx.Module):
    """Joint limits by penalty forces (the law: the module docstring), one law for every limited joint of a tree, its
    ``ke`` and ``kd`` shared or one per limited joint.

    Args:
        ke: limit stiffness [N m/rad or N/m], > 0: a number, or a 1-d array with one per joint that has a ``range``,
            in the joints' order (DFlex's SNU humanoid scales it by each joint's child mass).
        kd: limit damping [N m s/rad or N s/m], >= 0, applied outside the range only; a number or one per limited
            joint.

    Attributes:
        ke: limit stiffness [N m/rad or N/m], a 0-d or 1-d array (differentiable).
        kd: limit damping [N m s/rad or N s/m], a 0-d or 1-d array (differentiable).
    """

    ke: Float[Array, "*joints"]
    kd: Float[Array, "*joints"]

    def __init__(self, ke: Float[ArrayLike, "*joints"], kd: Float[ArrayLike, "*joints"] = 0.0):
        self.ke = _parameter("ke", ke, positive=True)
        self.kd = _parameter("kd", kd, positive=False)

    def check_count(self, limited: int, owner: str = "Tree") -> None:
        """Raise a ``ValueError`` naming ``owner`` unless every per-joint parameter has ``limited`` entries."""
        for name in ("ke", "kd"):
            x = getattr(self, name)
            if jnp.ndim(x) == 1 and jnp.shape(x)[0] != limited:
                raise ValueError(f"{owner}.limits.{name} has {jnp.shape(x)[0]} values, one per limited joint, but "
                                 f"{limited} joints have a range")

    def _joints(self, x, q, axis: int):
        """A per-joint parameter shaped to broadcast along ``q``'s joint ``axis`` (a scalar as it is)."""
        if jnp.ndim(x) == 0 or axis % q.ndim == q.ndim - 1:
            return x
        return jnp.reshape(x, (-1,) + (1,) * (q.ndim - 1 - axis % q.ndim))

    def forces(self, q, qd, lower, upper, axis: int = -1):
        """The limits' generalized forces, by the law of the module docstring.

        Args:
            q: joint coordinates [rad or m]; any shape.
            qd: joint velocities [rad/s or m/s]; broadcast against ``q``.
            lower: the ranges' lower bounds [rad or m]; broadcast against ``q``.
            upper: the ranges' upper bounds [rad or m]; broadcast against ``q``.
            axis: the axis of ``q`` that runs over the limited joints (where per-joint ``ke`` and ``kd`` apply).

        Returns:
            ``ke (bound - q) - kd qd`` outside the range, 0 inside (and on a bound) [N m or N], of the broadcast
            shape.
        """
        below = jnp.where(q < lower, q - lower, 0.0)
        above = jnp.where(q > upper, q - upper, 0.0)
        outside = (q < lower) | (q > upper)
        ke, kd = self._joints(self.ke, q, axis), self._joints(self.kd, q, axis)
        return -ke * (below + above) - jnp.where(outside, kd * qd, 0.0)

    def energy(self, q, lower, upper, axis: int = -1):
        """The limit springs' potential energy.

        Args:
            q: joint coordinates [rad or m]; any shape.
            lower: the ranges' lower bounds [rad or m]; broadcast against ``q``.
            upper: the ranges' upper bounds [rad or m]; broadcast against ``q``.
            axis: the axis of ``q`` that runs over the limited joints.

        Returns:
            ``1/2 ke (q - bound)^2`` [J] outside the range, 0 inside, elementwise.
        """
        v = jnp.where(q < lower, q - lower, 0.0) + jnp.where(q > upper, q - upper, 0.0)
        return 0.5 * self._joints(self.ke, q, axis) * v * v
