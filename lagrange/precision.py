"""``astype``: a model, states or any pytree in another floating type, e.g. a float32 model under JAX's 64-bit mode.

The library computes in the type of what it is given: a float32 chain or tree with float32 states stays in float32
even where ``jax_enable_x64`` is on (its static constants and the solvers' times follow the state's dtype).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp


def astype(tree, dtype):
    """``tree`` with every floating array cast to ``dtype``; integer and boolean arrays, Python numbers and static
    fields are left as they are.

    Args:
        tree: a [`Chain`][lagrange.chain.Chain], a [`Tree`][lagrange.model.tree.Tree], a task, states ``(q, qd)`` or any
            pytree of arrays.
        dtype: a floating type: ``jnp.float32``, ``jnp.float64``, ``jnp.float16`` or ``jnp.bfloat16``.

    Raises:
        ValueError: ``dtype`` is not a floating type, or is float64 while JAX's 64-bit mode is off (where the cast
            would silently give float32).
    """
    try:  # jnp.dtype(None) is float64 and an unknown name a TypeError: both refused here by name
        dt = None if dtype is None else jnp.dtype(dtype)
    except TypeError:
        dt = None
    if dt is None or not jnp.issubdtype(dt, jnp.floating):
        raise ValueError("dtype must be a floating type (float16, bfloat16, float32 or float64), got "
                         f"{repr(dtype) if dt is None else dt}")
    if jax.dtypes.canonicalize_dtype(dt) != dt:  # float64 with the 64-bit mode off
        raise ValueError("dtype float64 needs JAX's 64-bit mode: turn the jax_enable_x64 option on before creating "
                         "any array (docs: Getting started, Precision), or use float32")
    return jax.tree.map(lambda a: a.astype(dt) if eqx.is_inexact_array(a) else a, tree)
