"""A running observation normaliser as a pure object (mean/variance by Chan's parallel merge)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp


class Normalizer(eqx.Module):
    """Running mean and variance of observations (size,), applied as ``clip((x - mean) / std, -clip, clip)``.

    Pure: :meth:`update` returns a new normaliser; nothing is mutated. Before the first update
    (``count == 0``) it is the identity up to clipping.
    """

    mean: jax.Array
    var: jax.Array
    count: jax.Array
    clip: float = eqx.field(static=True, default=5.0)
    eps: float = eqx.field(static=True, default=1e-6)

    @classmethod
    def create(cls, size: int, *, clip: float = 5.0, dtype=None) -> "Normalizer":
        if size < 1:
            raise ValueError(f"Normalizer size must be >= 1, got {size}")
        if not clip > 0:
            raise ValueError(f"Normalizer clip must be > 0, got {clip}")
        dtype = dtype or jnp.zeros(()).dtype
        return cls(jnp.zeros(size, dtype), jnp.ones(size, dtype), jnp.zeros((), dtype), clip=clip)

    def update(self, obs) -> "Normalizer":
        """Merge a batch of observations (..., size) into the running statistics (no gradient flows)."""
        obs = jax.lax.stop_gradient(jnp.asarray(obs)).reshape(-1, self.mean.shape[0]).astype(self.mean.dtype)
        n = jnp.asarray(obs.shape[0], self.mean.dtype)
        bmean = jnp.mean(obs, axis=0)
        bvar = jnp.var(obs, axis=0)
        total = self.count + n
        delta = bmean - self.mean
        mean = self.mean + delta * (n / total)
        old_var = jnp.where(self.count > 0, self.var, 0.0)
        m2 = old_var * self.count + bvar * n + delta**2 * self.count * n / total
        return Normalizer(mean, m2 / total, total, clip=self.clip, eps=self.eps)

    def __call__(self, obs):
        z = (obs - self.mean) / jnp.sqrt(self.var + self.eps)
        return jnp.clip(z, -self.clip, self.clip)
