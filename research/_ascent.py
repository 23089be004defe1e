"""Gradient ascent that keeps the best point it has seen: the optimiser shared by the trajectory refinements
(``refine_swingup``, ``swingup_lqr``), whose objectives are chaotic enough that the last iterate is often not the
best."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax


def adam_best_seen(value, z, *, steps: int, learning_rate: float):
    """Adam (cosine-decayed ``learning_rate`` -> 1 %) ascending ``value(z)`` for ``steps`` updates.

    Returns ``(best z, best value, starting value)``, the best over the start, every iterate and the final one. A
    non-finite value never counts as better (a non-finite start counts as ``-inf``, so any finite iterate beats it;
    ``-inf`` comes back if none is finite) and non-finite gradient entries are zeroed. Pure: ``jit`` and ``vmap``
    it (one independent ascent per mapped ``z``)."""
    opt = optax.adam(optax.cosine_decay_schedule(learning_rate, max(steps, 1), 0.01))
    value_and_grad = jax.value_and_grad(value)

    def body(carry, _):
        z, state, best_z, best = carry
        v, g = value_and_grad(z)
        better = jnp.isfinite(v) & (v > best)
        best_z, best = jnp.where(better, z, best_z), jnp.where(better, v, best)
        upd, state = opt.update(jnp.where(jnp.isfinite(g), -g, 0.0), state)
        return (optax.apply_updates(z, upd), state, best_z, best), None

    start = value(z)
    first = jnp.where(jnp.isfinite(start), start, -jnp.inf)
    (z, _, best_z, best), _ = jax.lax.scan(body, (z, opt.init(z), z, first), None, length=steps)
    last = value(z)  # the last update is not scored inside the loop
    better = jnp.isfinite(last) & (last > best)
    return jnp.where(better, z, best_z), jnp.where(better, last, best), start
