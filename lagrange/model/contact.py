"""Ground contact by penalty forces (DFlex's law, in the plane), differentiable almost everywhere.

Contact geometry belongs to links: points ``(x, z)`` in a link's frame with a radius ``r`` (``Link(contacts=...)``; a
capsule contributes its two end points, a sphere its centre). The ground is the level line ``z = ground``. A point's
lowest spot ``s = p - r e_z`` below the ground at depth ``d = ground - s_z > 0``, whose material velocity (the link's
velocity at ``s``) has the normal part ``vn`` and the part along the ground ``vt``, receives at ``s`` the force

- normal (along ``+z``): ``fn = ke d + kd d max(-vn, 0)``,
- along the ground: ``ft = -clip(kf vt, -mu ke d, mu ke d)``,

and nothing where ``d <= 0``. The generalized force is ``J_s^T (ft, fn)`` with ``J_s`` the Jacobian of the material
point at ``s``. The potential energy of the springs is ``1/2 ke d^2`` per point.

Gradients stay finite everywhere: the law is a polynomial in ``d``, ``vn`` and ``vt`` clipped and selected with
``where`` (both sides finite; at ``d = 0`` and ``vn = 0`` the derivative is the one-sided one of the zero side), and no
direction is normalised (the ground's normal is constant), so ``d = 0``, ``vt = 0`` and ``vn = 0`` exactly give finite
forward- and reverse-mode derivatives. The parameters are arrays: ``jax.grad`` with respect to ``ke``, ``kd``, ``kf``,
``mu`` and ``ground`` works (contact system identification).

This is DFlex's penalty model (NVlabs/DiffRL at commit 6b8d695, ``dflex/dflex/sim.py``, ``eval_rigid_contacts_art``),
not MuJoCo's soft-constraint solver; results compared with MuJoCo's contact agree in kind, not to round-off. The docs'
"Contact and joint limits" page says what differs from DFlex and from MuJoCo.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float


def scalar_parameter(cls: str, name: str, value, *, positive: bool = False):
    """A law's real scalar parameter as a JAX array, checked when concrete.

    Args:
        cls: the law's class name, for the messages.
        name: the parameter's name, for the messages.
        value: a real scalar (a Python number or a 0-d array), or a traced value (not checked).
        positive: require ``> 0`` instead of ``>= 0``.

    Returns:
        ``value`` as a 0-d array of JAX's default float type.

    Raises:
        TypeError: for a bool, a string, ``None`` or a non-number.
        ValueError: for an array that is not 0-d, a non-finite value, or one that breaks the sign rule.
    """
    if isinstance(value, (bool, str)) or value is None:
        raise TypeError(f"{cls}.{name} must be a real number, got {value!r}")
    if not isinstance(value, jax.core.Tracer):
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as err:
            raise TypeError(f"{cls}.{name} must be a real number, got {value!r}") from err
        if v.shape != ():
            raise ValueError(f"{cls}.{name} must be a scalar, got shape {v.shape}")
        if not math.isfinite(float(v)) or (float(v) <= 0 if positive else float(v) < 0):
            raise ValueError(f"{cls}.{name} must be finite and {'> 0' if positive else '>= 0'}, got {float(v)}")
        return jax.device_put(v.astype(jax.dtypes.canonicalize_dtype(float)))
    return jnp.asarray(value, jax.dtypes.canonicalize_dtype(float))


class PenaltyContact(eqx.Module):
    """Ground contact by penalty forces, one law for every contact point of a chain (the law: the module docstring).

    Args:
        ke: contact stiffness [N/m], > 0.
        kd: contact damping [N s/m^2]: the normal force gains ``kd d`` per m/s of approach, >= 0.
        kf: friction's viscous gain [N s/m], >= 0.
        mu: friction coefficient, >= 0: the friction force is at most ``mu ke d``.
        ground: the ground's height [m] (the level line ``z = ground``).

    Attributes:
        ke: contact stiffness [N/m], a 0-d array (differentiable, as are the others).
        kd: contact damping [N s/m^2], a 0-d array.
        kf: friction's viscous gain [N s/m], a 0-d array.
        mu: friction coefficient, a 0-d array.
        ground: the ground's height [m], a 0-d array.
    """

    ke: Float[Array, ""]
    kd: Float[Array, ""]
    kf: Float[Array, ""]
    mu: Float[Array, ""]
    ground: Float[Array, ""]

    def __init__(self, ke: Float[ArrayLike, ""], kd: Float[ArrayLike, ""], kf: Float[ArrayLike, ""],
                 mu: Float[ArrayLike, ""], ground: Float[ArrayLike, ""] = 0.0):
        self.ke = scalar_parameter("PenaltyContact", "ke", ke, positive=True)
        self.kd = scalar_parameter("PenaltyContact", "kd", kd)
        self.kf = scalar_parameter("PenaltyContact", "kf", kf)
        self.mu = scalar_parameter("PenaltyContact", "mu", mu)
        if isinstance(ground, (bool, str)) or ground is None:
            raise TypeError(f"PenaltyContact.ground must be a real number (a height in m), got {ground!r}")
        g = ground if isinstance(ground, jax.core.Tracer) else np.asarray(ground, dtype=float)
        if not isinstance(g, jax.core.Tracer) and (g.shape != () or not math.isfinite(float(g))):
            raise ValueError(f"PenaltyContact.ground must be a finite scalar height in m, got {ground!r}")
        self.ground = jnp.asarray(g, jax.dtypes.canonicalize_dtype(float))

    def _normal(self, depth, vn):
        """``(fn, bound)``: the normal force ``ke d + kd d max(-vn, 0)`` and friction's bound ``mu ke d``,
        ``d = max(depth, 0)``."""
        d = jnp.where(depth > 0, depth, 0.0)
        return self.ke * d + self.kd * d * jnp.where(vn < 0, -vn, 0.0), self.mu * self.ke * d

    def forces(self, depth, vn, vt):
        """The contact forces at spots below the ground, by the law of the module docstring.

        Args:
            depth: the spots' depth below the ground [m], positive below it; any shape.
            vn: the spots' velocity along the ground's normal ``+z`` [m/s]; broadcast against ``depth``.
            vt: the spots' velocity along the ground ``+x`` [m/s]; broadcast against ``depth``.

        Returns:
            ``(fn, ft)``: the normal force along ``+z`` and the friction force along ``+x`` [N], of the broadcast
            shape; zero where ``depth <= 0``.
        """
        fn, bound = self._normal(depth, vn)
        return fn, -jnp.clip(self.kf * vt, -bound, bound)

    def forces_3d(self, depth, vn, vt):
        """The contact forces on a level ground in 3-D: the normal force as :meth:`forces`, the friction
        ``-(vt / |vt|) min(kf |vt|, mu ke d)`` against the tangential velocity ``vt`` (in the plane ``-clip(kf vt,
        -mu ke d, mu ke d)`` of :meth:`forces`).

        Written as ``-vt min(kf, mu ke d / |vt|)`` with the viscous branch taken wherever ``kf |vt| <= mu ke d``
        (``vt = 0`` included) and ``|vt|`` replaced by 1 where it is 0 (a branch ``where`` then discards), so that
        the value and the gradient are finite and exact at ``vt = 0`` and at ``d = 0``.

        Args:
            depth: the spots' depth below the ground [m], positive below it; shape ``(...)``.
            vn: the spots' velocity along the ground's normal ``+z`` [m/s], ``(...)``.
            vt: the spots' velocity along the ground ``(x, y)`` [m/s], ``(..., 2)``.

        Returns:
            ``(fn, ft)``: the normal force ``(...)`` and the friction ``(..., 2)`` [N]; zero where ``depth <= 0``.
        """
        fn, bound = self._normal(depth, vn)
        v2 = jnp.sum(vt * vt, axis=-1)
        speed = jnp.sqrt(jnp.where(v2 > 0, v2, 1.0))
        viscous = (v2 == 0) | (self.kf * speed <= bound)  # a comparison: no gradient flows through it
        gain = jnp.where(viscous, self.kf, bound / speed)
        return fn, -gain[..., None] * vt

    def energy(self, depth):
        """The penalty spring's potential energy.

        Args:
            depth: the spots' depth below the ground [m], positive below it; any shape.

        Returns:
            ``1/2 ke d^2`` [J] for ``d = max(depth, 0)``, elementwise.
        """
        d = jnp.where(depth > 0, depth, 0.0)
        return 0.5 * self.ke * d * d
