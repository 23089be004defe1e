"""A running observation normaliser as a pure object (mean/variance by Chan's parallel merge)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import DTypeLike
from jaxtyping import Array, ArrayLike, Float

from policies.base import check_size


def _observations(norm, obs) -> Array:
    """``obs`` as an array whose last axis is the normaliser's size, or a ``ValueError`` naming the shapes."""
    obs = jnp.asarray(obs)
    if obs.ndim < 1 or obs.shape[-1] != norm.mean.shape[0]:
        raise ValueError(f"{type(norm).__name__}: observations must have shape (*batch, size = {norm.mean.shape[0]}), "
                         f"got {obs.shape}")
    return obs


class Normalizer(eqx.Module):
    """Running mean and variance of observations (size,), applied as ``clip((x - mean) / std, -clip, clip)``.

    Pure: :meth:`update` returns a new normaliser; nothing is mutated. Before the first update
    (``count == 0``) it is the identity up to clipping. Build one with :meth:`create`.

    Args:
        mean: running mean of each observation component, shape ``(size,)``, in the observation's units.
        var: running (population) variance of each component, shape ``(size,)``, in those units squared.
        count: scalar, number of observations merged so far (stored as a float).
        clip: bound on the normalised output (dimensionless, in standard deviations), > 0; static.
        eps: added to ``var`` before the square root; static.
    """

    mean: Float[Array, " size"]
    var: Float[Array, " size"]
    count: Float[Array, ""]
    clip: float = eqx.field(static=True, default=5.0)
    eps: float = eqx.field(static=True, default=1e-6)

    @classmethod
    def create(cls, size: int, *, clip: float = 5.0, dtype: DTypeLike | None = None) -> Normalizer:
        """An empty normaliser: ``mean = 0``, ``var = 1``, ``count = 0``.

        Args:
            size: length of the observation vector, >= 1.
            clip: bound on the normalised output [standard deviations], > 0.
            dtype: floating dtype of the statistics; ``None`` for JAX's default.
        """
        size = check_size("Normalizer", "size", size)
        if isinstance(clip, bool) or not clip > 0:
            raise ValueError(f"Normalizer clip must be a number > 0 (standard deviations; inf: no clipping), got "
                             f"{clip!r}")
        dtype = dtype or jnp.zeros(()).dtype
        return cls(jnp.zeros(size, dtype), jnp.ones(size, dtype), jnp.zeros((), dtype), clip=clip)

    def update(self, obs: Float[ArrayLike, "*batch size"]) -> Normalizer:
        """Merge a batch of observations into the running statistics (no gradient flows).

        Args:
            obs: observations, shape ``(*batch, size)``; every leading index is one sample.

        Returns:
            The updated normaliser (``self`` is unchanged).
        """
        obs = _observations(self, obs)
        obs = jax.lax.stop_gradient(obs).reshape(-1, self.mean.shape[0]).astype(self.mean.dtype)
        n = jnp.asarray(obs.shape[0], self.mean.dtype)
        bmean = jnp.mean(obs, axis=0)
        bvar = jnp.var(obs, axis=0)
        total = self.count + n
        delta = bmean - self.mean
        mean = self.mean + delta * (n / total)
        old_var = jnp.where(self.count > 0, self.var, 0.0)
        m2 = old_var * self.count + bvar * n + delta**2 * self.count * n / total
        return Normalizer(mean, m2 / total, total, clip=self.clip, eps=self.eps)

    def __call__(self, obs: Float[ArrayLike, "*batch size"]) -> Float[Array, "*batch size"]:
        """Normalise observations: ``clip((obs - mean) / sqrt(var + eps), -clip, clip)``.

        Args:
            obs: observations, shape ``(*batch, size)``, in the task's units.

        Returns:
            Shape ``(*batch, size)``, dimensionless (standard deviations).
        """
        z = (_observations(self, obs) - self.mean) / jnp.sqrt(self.var + self.eps)
        return jnp.clip(z, -self.clip, self.clip)


class BraxNormalizer(eqx.Module):
    """Brax v1's running observation normaliser (``brax/training/normalization.py``), the one the CE-APG authors used.

    It keeps the observation count ``steps``, the running ``mean`` and the summed squared deviations ``m2``, starting
    from Brax's prior ``steps = 0, mean = 0, m2 = 1``; it applies ``clip((obs - mean) / sqrt(var), -5, 5)`` with
    ``var = clip(m2 / (steps + 1), 1e-6, 1e6)``. Unlike :class:`Normalizer` the prior never washes out: after ``N``
    observations of a still system ``var`` is about ``1 / (N + 1)``, so at the start of training any motion is
    clipped to +-5. Same interface as :class:`Normalizer` (:meth:`create`, :meth:`update`, call).

    Args:
        steps: number of observations merged, scalar (a float, as Brax keeps it).
        mean: running mean, shape ``(size,)``, in the observation's units.
        m2: prior plus summed squared deviations from the mean, shape ``(size,)``, in those units squared.
    """

    steps: Float[Array, ""]
    mean: Float[Array, " size"]
    m2: Float[Array, " size"]

    @classmethod
    def create(cls, size: int, *, dtype: DTypeLike | None = None) -> BraxNormalizer:
        """An empty normaliser with Brax's prior: ``steps = 0``, ``mean = 0``, ``m2 = 1``.

        Args:
            size: length of the observation vector, >= 1.
            dtype: floating dtype of the statistics; ``None`` for JAX's default.
        """
        size = check_size("BraxNormalizer", "size", size)
        dtype = dtype or jnp.zeros(()).dtype
        return cls(jnp.zeros((), dtype), jnp.zeros(size, dtype), jnp.ones(size, dtype))

    def update(self, obs: Float[ArrayLike, "*batch size"]) -> BraxNormalizer:
        """Merge a batch of observations (Brax's Welford update; no gradient flows).

        Args:
            obs: observations, shape ``(*batch, size)``; every leading index is one sample.

        Returns:
            The updated normaliser (``self`` is unchanged).
        """
        obs = jax.lax.stop_gradient(_observations(self, obs)).reshape(-1, self.mean.shape[0]).astype(self.mean.dtype)
        total = self.steps + obs.shape[0]
        to_old = obs - self.mean
        mean = self.mean + jnp.sum(to_old / total, axis=0)
        m2 = self.m2 + jnp.sum((obs - mean) * to_old, axis=0)
        return BraxNormalizer(total, mean, m2)

    def __call__(self, obs: Float[ArrayLike, "*batch size"]) -> Float[Array, "*batch size"]:
        """Normalise observations: ``clip((obs - mean) / sqrt(clip(m2 / (steps + 1), 1e-6, 1e6)), -5, 5)``.

        Args:
            obs: observations, shape ``(*batch, size)``, in the task's units.

        Returns:
            Shape ``(*batch, size)``, dimensionless.
        """
        var = jnp.clip(self.m2 / (self.steps + 1.0), 1e-6, 1e6)
        return jnp.clip((_observations(self, obs) - self.mean) / jnp.sqrt(var), -5.0, 5.0)
