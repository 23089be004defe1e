"""Trace-time algebra on scalars that folds the constants 0 and 1 before XLA sees them.

A *scalar* here is either a Python ``float`` (a constant known while tracing) or a JAX array
(a value that is only known at run time; under ``vmap`` it carries the batch). Every helper
returns a Python float when the answer is known at trace time, so that multiplications by 0
or 1, additions of 0 and whole dead branches never reach the compiled program. XLA cannot do
this folding itself for floats (``0 * x`` is not ``0`` when ``x`` is ``inf`` or ``nan``).

The symmetric positive-definite solve of the unrolled derivation is written over these scalars too
(:func:`solve_spd`): for the few-link chains it serves (shorter than ``lagrange.dynamics.RECURSIVE_MIN``; longer
ones reach ``qdd`` by ABA and need no solve), a LAPACK call inside a ``scan`` costs far more than the arithmetic, and
a division, the adjugate or an LDL^T factorisation written out over scalars fuses into the surrounding elementwise
kernel instead.
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


def solve_spd(M, b, like, *, pivots: bool = False):
    """Solve ``M x = b`` for symmetric positive-definite ``M``.

    ``M`` is a nested list of scalars (only ``M[i][j]`` with ``j <= i`` is read), ``b`` a list of
    scalars. Returns a list of scalars; with ``pivots=True``, also the list of scalars that are all
    positive exactly when ``M`` is positive definite, for a positive semi-definite ``M``: ``M[0][0]``
    (n = 1), the determinant (n = 2, 3) or the pivots of LDL^T.
    """
    n = len(b)
    if n == 1:
        x = [div(b[0], M[0][0])]
        return (x, [M[0][0]]) if pivots else x
    if n in (2, 3):
        x, det = _solve_adjugate(M, b)
        return (x, [det]) if pivots else x
    L = [[0.0] * n for _ in range(n)]
    inv_d = [0.0] * n
    d = [0.0] * n
    for j in range(n):
        dj = M[j][j]
        for k in range(j):
            dj = sub(dj, mul(mul(L[j][k], L[j][k]), d[k]))
        d[j] = dj
        inv_d[j] = div(1.0, dj)
        for i in range(j + 1, n):
            lij = M[i][j]
            for k in range(j):
                lij = sub(lij, mul(mul(L[i][k], L[j][k]), d[k]))
            L[i][j] = mul(lij, inv_d[j])
    y = list(b)
    for i in range(n):
        for k in range(i):
            y[i] = sub(y[i], mul(L[i][k], y[k]))
    x = [mul(y[i], inv_d[i]) for i in range(n)]
    for i in reversed(range(n)):
        for k in range(i + 1, n):
            x[i] = sub(x[i], mul(L[k][i], x[k]))
    return (x, d) if pivots else x


def _solve_adjugate(M, b):
    """Cramer's rule for symmetric 2x2 and 3x3 systems: one division, as written by hand. Returns ``(x, det M)``."""
    if len(b) == 2:
        a, c, d = M[0][0], M[1][0], M[1][1]
        det = sub(mul(a, d), mul(c, c))
        inv_det = div(1.0, det)
        return [
            mul(sub(mul(d, b[0]), mul(c, b[1])), inv_det),
            mul(sub(mul(a, b[1]), mul(c, b[0])), inv_det),
        ], det
    a, bb, c = M[0][0], M[1][0], M[2][0]
    d, e, f = M[1][1], M[2][1], M[2][2]
    # cofactors of the symmetric matrix [[a, bb, c], [bb, d, e], [c, e, f]]
    A = sub(mul(d, f), mul(e, e))
    B = sub(mul(c, e), mul(bb, f))
    C = sub(mul(bb, e), mul(c, d))
    D = sub(mul(a, f), mul(c, c))
    E = sub(mul(bb, c), mul(a, e))
    F = sub(mul(a, d), mul(bb, bb))
    det = total([mul(a, A), mul(bb, B), mul(c, C)])
    inv_det = div(1.0, det)
    r0, r1, r2 = b
    return [
        mul(total([mul(A, r0), mul(B, r1), mul(C, r2)]), inv_det),
        mul(total([mul(B, r0), mul(D, r1), mul(E, r2)]), inv_det),
        mul(total([mul(C, r0), mul(E, r1), mul(F, r2)]), inv_det),
    ], det


def to_array(M, like, symmetric: bool = False):
    n = len(M)
    rows = []
    for i in range(n):
        row = []
        for j in range(n):
            x = M[max(i, j)][min(i, j)] if symmetric else M[i][j]
            row.append(as_array(x, like))
        rows.append(jnp.stack(row, axis=-1))
    return jnp.stack(rows, axis=-2)
