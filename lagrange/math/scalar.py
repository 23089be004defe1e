"""Trace-time algebra on scalars that folds the constants 0 and 1 before XLA sees them.

A *scalar* here is either a Python ``float`` (a constant known while tracing) or a JAX array
(a value that is only known at run time; under ``vmap`` it carries the batch). Every helper
returns a Python float when the answer is known at trace time, so that multiplications by 0
or 1, additions of 0 and whole dead branches never reach the compiled program. XLA cannot do
this folding itself for floats (``0 * x`` is not ``0`` when ``x`` is ``inf`` or ``nan``).
"""

from __future__ import annotations

import math

import jax.numpy as jnp

Scalar = float | jnp.ndarray


def is_const(x) -> bool:
    return isinstance(x, (int, float))


def is_zero(x) -> bool:
    return is_const(x) and x == 0


def is_one(x) -> bool:
    return is_const(x) and x == 1


class _Neg:
    """``-v`` for a run-time ``v``, kept symbolic (see :func:`negated`)."""

    __slots__ = ("v",)

    def __init__(self, v):
        self.v = v


def sign_and_magnitude(x):
    """``(negative, magnitude)``: ``x`` is ``-magnitude`` if ``negative``, else ``magnitude`` (a sign kept symbolic by
    :func:`negated` is taken off; any other ``x`` is its own magnitude)."""
    return _split(x)


def _split(x):
    """``(negative, magnitude)``: ``x`` is ``-magnitude`` if ``negative``, else ``magnitude``."""
    return (True, x.v) if isinstance(x, _Neg) else (False, x)


def negated(a: Scalar) -> Scalar:
    """``-a``, with the sign kept symbolic for a run-time ``a``: the helpers below fold it into a constant factor or
    turn an addition into a subtraction, so it rarely reaches XLA at all; :func:`as_array` applies what is left. Only
    code whose results leave through these helpers and :func:`as_array` may create one (the relative-angle
    derivation of :mod:`lagrange.planar.unitvec` and the dynamics built on it)."""
    if is_const(a):
        return float(-a)
    if isinstance(a, _Neg):
        return a.v
    return _Neg(a)


def neg(a: Scalar) -> Scalar:
    """``-a``, a run-time ``a`` emitted as ``a * -1.0`` (the same value: multiplying by -1 is exact). A sign that
    reaches XLA inside a fused loop, as a ``negate`` or as this multiplication, can cost the loop its vectorization on
    the CPU (``python -m research.xla_vectorization``: the cartpole's closed form 1.5-1.9x slower with one), so the
    relative-angle derivation keeps its signs symbolic (:func:`negated`); this is the fallback."""
    if is_const(a):
        return float(-a)
    if isinstance(a, _Neg):
        return a.v
    return a * -1.0


def add(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a):
        return b
    if is_zero(b):
        return a
    na, a0 = _split(a)
    nb, b0 = _split(b)
    if na and nb:
        return negated(add(a0, b0))
    if na:
        return sub(b, a0)
    if nb:
        return sub(a, b0)
    if is_const(a) and is_const(b):
        return float(a + b)
    return a + b


def sub(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(b):
        return a
    if is_zero(a):
        return neg(b)
    na, a0 = _split(a)
    nb, b0 = _split(b)
    if na and nb:
        return sub(b0, a0)
    if na:
        return negated(add(a0, b))
    if nb:
        return add(a, b0)
    if is_const(a) and is_const(b):
        return float(a - b)
    return a - b


def _signed(negative: bool, a0, b0, op):
    """``op(a0, b0)``, negated if ``negative``, the sign folded into a constant operand when there is one."""
    if not negative:
        return op(a0, b0)
    if is_const(a0):
        return op(float(-a0), b0)
    if is_const(b0):
        return op(a0, float(-b0))
    return negated(op(a0, b0))


def mul(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a) or is_zero(b):
        return 0.0
    if is_one(a):
        return b
    if is_one(b):
        return a
    na, a0 = _split(a)
    nb, b0 = _split(b)
    if na or nb:
        return _signed(na != nb, a0, b0, mul)
    if is_const(a) and is_const(b):
        return float(a * b)
    if is_const(a) and a == -1:
        return neg(b)
    if is_const(b) and b == -1:
        return neg(a)
    return a * b


def div(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a):
        return 0.0
    if is_one(b):
        return a
    na, a0 = _split(a)
    nb, b0 = _split(b)
    if na or nb:
        return _signed(na != nb, a0, b0, div)
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
    if isinstance(x, _Neg):
        x = neg(x.v)
    if is_const(x):
        if like is None:
            return jnp.asarray(x)
        return jnp.full(jnp.shape(like), x, dtype=jnp.result_type(like))
    if like is not None and jnp.shape(x) != jnp.shape(like):
        # a parameter-only entry (e.g. a constant mass-matrix entry) under batched q
        return jnp.broadcast_to(x, jnp.broadcast_shapes(jnp.shape(x), jnp.shape(like)))
    return x


def cos_sin(angle: float) -> tuple[float, float]:
    """``(cos, sin)`` of a static angle, with values within 1e-15 of 0 snapped to 0 (so that an offset of pi or
    pi/2 adds no round-off term)."""
    c, sn = math.cos(angle), math.sin(angle)
    return (0.0 if abs(c) < 1e-15 else c), (0.0 if abs(sn) < 1e-15 else sn)
