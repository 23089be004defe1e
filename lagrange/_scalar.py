"""Trace-time algebra on scalars that folds the constants 0 and 1 before XLA sees them.

A *scalar* here is either a Python ``float`` (a constant known while tracing) or a JAX array
(a value that is only known at run time; under ``vmap`` it carries the batch). Every helper
returns a Python float when the answer is known at trace time, so that multiplications by 0
or 1, additions of 0 and whole dead branches never reach the compiled program. XLA cannot do
this folding itself for floats (``0 * x`` is not ``0`` when ``x`` is ``inf`` or ``nan``).
"""

from __future__ import annotations

from typing import Union

import jax.numpy as jnp

Scalar = Union[float, jnp.ndarray]


def is_const(x) -> bool:
    return isinstance(x, (int, float))


def is_zero(x) -> bool:
    return is_const(x) and x == 0


def is_one(x) -> bool:
    return is_const(x) and x == 1


def add(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a):
        return b
    if is_zero(b):
        return a
    if is_const(a) and is_const(b):
        return float(a + b)
    return a + b


def sub(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(b):
        return a
    if is_zero(a):
        return neg(b)
    if is_const(a) and is_const(b):
        return float(a - b)
    return a - b


def neg(a: Scalar) -> Scalar:
    if is_const(a):
        return float(-a)
    return -a


def mul(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a) or is_zero(b):
        return 0.0
    if is_one(a):
        return b
    if is_one(b):
        return a
    if is_const(a) and is_const(b):
        return float(a * b)
    if is_const(a) and a == -1:
        return -b
    if is_const(b) and b == -1:
        return -a
    return a * b


def div(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a):
        return 0.0
    if is_one(b):
        return a
    if is_const(a) and is_const(b):
        return float(a / b)
    return a / b


def total(terms) -> Scalar:
    """Sum of an iterable of scalars, constants folded."""
    out: Scalar = 0.0
    for t in terms:
        out = add(out, t)
    return out


def dot(xs, ys) -> Scalar:
    return total(mul(x, y) for x, y in zip(xs, ys))


def as_array(x, like=None):
    """A scalar as a JAX array (constants become arrays shaped and typed like ``like``)."""
    if is_const(x):
        if like is None:
            return jnp.asarray(x)
        return jnp.full(jnp.shape(like), x, dtype=jnp.result_type(like))
    if like is not None and jnp.shape(x) != jnp.shape(like):
        # a parameter-only entry (e.g. a constant mass-matrix entry) under batched q
        return jnp.broadcast_to(x, jnp.broadcast_shapes(jnp.shape(x), jnp.shape(like)))
    return x

