"""Symmetric positive-definite solves: small ones unrolled at trace time, and a factor-once solver for arrays.

For the few-link chains this module serves (those shorter than
``lagrange.dynamics.RECURSIVE_MIN``; longer ones reach ``qdd`` by ABA and need no solve), a LAPACK
call inside a ``scan`` costs far more than the arithmetic. A division, the adjugate or an LDL^T
factorisation written out over scalars fuses into the surrounding elementwise kernel instead.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from lagrange.math import scalar as s


def solve_spd(M, b, like, *, pivots: bool = False):
    """Solve ``M x = b`` for symmetric positive-definite ``M``.

    ``M`` is a nested list of scalars (only ``M[i][j]`` with ``j <= i`` is read), ``b`` a list of
    scalars. Returns a list of scalars; with ``pivots=True``, also the list of scalars that are all
    positive exactly when ``M`` is positive definite, for a positive semi-definite ``M``: ``M[0][0]``
    (n = 1), the determinant (n = 2, 3) or the pivots of LDL^T.
    """
    n = len(b)
    if n == 1:
        x = [s.div(b[0], M[0][0])]
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
            dj = s.sub(dj, s.mul(s.mul(L[j][k], L[j][k]), d[k]))
        d[j] = dj
        inv_d[j] = s.div(1.0, dj)
        for i in range(j + 1, n):
            lij = M[i][j]
            for k in range(j):
                lij = s.sub(lij, s.mul(s.mul(L[i][k], L[j][k]), d[k]))
            L[i][j] = s.mul(lij, inv_d[j])
    y = list(b)
    for i in range(n):
        for k in range(i):
            y[i] = s.sub(y[i], s.mul(L[i][k], y[k]))
    x = [s.mul(y[i], inv_d[i]) for i in range(n)]
    for i in reversed(range(n)):
        for k in range(i + 1, n):
            x[i] = s.sub(x[i], s.mul(L[k][i], x[k]))
    return (x, d) if pivots else x


def _solve_adjugate(M, b):
    """Cramer's rule for symmetric 2x2 and 3x3 systems: one division, as written by hand. Returns ``(x, det M)``."""
    if len(b) == 2:
        a, c, d = M[0][0], M[1][0], M[1][1]
        det = s.sub(s.mul(a, d), s.mul(c, c))
        inv_det = s.div(1.0, det)
        return [
            s.mul(s.sub(s.mul(d, b[0]), s.mul(c, b[1])), inv_det),
            s.mul(s.sub(s.mul(a, b[1]), s.mul(c, b[0])), inv_det),
        ], det
    a, bb, c = M[0][0], M[1][0], M[2][0]
    d, e, f = M[1][1], M[2][1], M[2][2]
    # cofactors of the symmetric matrix [[a, bb, c], [bb, d, e], [c, e, f]]
    A = s.sub(s.mul(d, f), s.mul(e, e))
    B = s.sub(s.mul(c, e), s.mul(bb, f))
    C = s.sub(s.mul(bb, e), s.mul(c, d))
    D = s.sub(s.mul(a, f), s.mul(c, c))
    E = s.sub(s.mul(bb, c), s.mul(a, e))
    F = s.sub(s.mul(a, d), s.mul(bb, bb))
    det = s.total([s.mul(a, A), s.mul(bb, B), s.mul(c, C)])
    inv_det = s.div(1.0, det)
    r0, r1, r2 = b
    return [
        s.mul(s.total([s.mul(A, r0), s.mul(B, r1), s.mul(C, r2)]), inv_det),
        s.mul(s.total([s.mul(B, r0), s.mul(D, r1), s.mul(E, r2)]), inv_det),
        s.mul(s.total([s.mul(C, r0), s.mul(E, r1), s.mul(F, r2)]), inv_det),
    ], det


def to_array(M, like, symmetric: bool = False):
    n = len(M)
    rows = []
    for i in range(n):
        row = []
        for j in range(n):
            x = M[max(i, j)][min(i, j)] if symmetric else M[i][j]
            row.append(s.as_array(x, like))
        rows.append(jnp.stack(row, axis=-1))
    return jnp.stack(rows, axis=-2)


def spd_solver(A):
    """``b -> A^-1 b`` for a (batch of) symmetric positive-definite array ``A`` of shape ``(*batch, n, n)``, factored
    once by Cholesky (for solving with the same matrix several times, as :class:`lagrange.MomentumEuler` does).

    Args:
        A: shape ``(*batch, n, n)``.

    Returns:
        A function of ``b`` (shape ``(*batch, n)``) returning ``A^-1 b`` (shape ``(*batch, n)``).
    """
    L = jnp.linalg.cholesky(A)

    def solve(b):
        y = jax.lax.linalg.triangular_solve(L, b[..., None], left_side=True, lower=True)
        return jax.lax.linalg.triangular_solve(L, y, left_side=True, lower=True, transpose_a=True)[..., 0]

    return solve
