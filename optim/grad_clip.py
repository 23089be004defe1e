"""Gradient clipping by global norm, the one function APG's inner step and SHAC's actor and critic call."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from jaxtyping import Array, ArrayLike, Float, PyTree

__all__ = ["clip_grad_norm"]


def clip_grad_norm(grads: PyTree, max_norm: float | None, *, norm: Float[ArrayLike, ""] | None = None,
                   eps: float | None = 1e-6) -> tuple[PyTree, Float[Array, ""]]:
    """Scale ``grads`` by ``min(1, max_norm / d)``, ``d`` the denominator of the convention chosen by ``eps``.

    Args:
        grads: a pytree of gradient arrays.
        max_norm: the largest global 2-norm to let through, > 0; None returns ``grads`` unchanged.
        norm: the global 2-norm to scale by (default ``optax.tree.norm(grads)``); a caller that masks a non-finite
            gradient passes the norm it masked.
        eps: ``d = norm + eps`` (PyTorch's ``clip_grad_norm_``, ``eps = 1e-6``, as the SHAC authors clip: the norm
            comes out slightly below ``max_norm``); None: ``d = max(norm, tiny)`` (the smallest normal float of the
            norm's dtype), exact clipping to ``max_norm`` that leaves a zero gradient zero.

    Returns:
        ``(clipped grads, norm)``.
    """
    norm = optax.tree.norm(grads) if norm is None else norm
    if max_norm is None:
        return grads, norm
    denominator = norm + eps if eps is not None else jnp.maximum(norm, jnp.finfo(jnp.result_type(norm)).tiny)
    coef = jnp.minimum(1.0, max_norm / denominator)
    return jax.tree_util.tree_map(lambda g: g * coef, grads), norm
