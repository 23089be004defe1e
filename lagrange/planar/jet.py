"""Sparse second-order forward-mode automatic differentiation, simplified at trace time.

A :class:`Jet` is a scalar function of the generalized coordinates ``q`` evaluated along a
trajectory with velocity ``qd``. It carries

- ``v``: its value,
- ``g``: its partial derivatives ``dv/dq_j`` as a sparse ``{j: scalar}`` map (absent = zero),
- ``vd``: its time derivative ``sum_j g_j qd_j``,
- ``a``: its second time derivative at zero acceleration, ``sum_jk d2v/dq_j dq_k qd_j qd_k``.

Arithmetic on jets applies the chain and product rules term by term with the folding helpers
of :mod:`lagrange.math.scalar`, so the derivative program that reaches XLA has no multiplications
by 0 or 1 and no terms for coordinates a quantity does not depend on. Passing ``qd=None``
makes every ``vd`` and ``a`` the constant 0, which removes all velocity terms (e.g. for the
mass matrix alone).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax.numpy as jnp

from lagrange.math import scalar as s


@dataclass(frozen=True)
class Jet:
    v: s.Scalar = 0.0
    g: dict = field(default_factory=dict)
    vd: s.Scalar = 0.0
    a: s.Scalar = 0.0

    @staticmethod
    def const(value) -> "Jet":
        return Jet(value)

    @staticmethod
    def coordinate(j: int, q_j, qd_j) -> "Jet":
        """The coordinate q_j itself."""
        return Jet(q_j, {j: 1.0}, qd_j, 0.0)

    def __add__(self, other: "Jet") -> "Jet":
        g = dict(self.g)
        for j, d in other.g.items():
            g[j] = s.add(g.get(j, 0.0), d)
        return Jet(s.add(self.v, other.v), g, s.add(self.vd, other.vd), s.add(self.a, other.a))

    def __neg__(self) -> "Jet":
        return Jet(s.neg(self.v), {j: s.neg(d) for j, d in self.g.items()}, s.neg(self.vd), s.neg(self.a))

    def __sub__(self, other: "Jet") -> "Jet":
        return self + (-other)

    def scale(self, c) -> "Jet":
        """Multiply by a quantity that does not depend on q (a parameter or a constant)."""
        if s.is_zero(c):
            return Jet()
        return Jet(
            s.mul(c, self.v),
            {j: s.mul(c, d) for j, d in self.g.items()},
            s.mul(c, self.vd),
            s.mul(c, self.a),
        )

    def __mul__(self, other: "Jet") -> "Jet":
        x, y = self, other
        g = {}
        for j in set(x.g) | set(y.g):
            g[j] = s.add(s.mul(x.v, y.g.get(j, 0.0)), s.mul(y.v, x.g.get(j, 0.0)))
        vd = s.add(s.mul(x.v, y.vd), s.mul(y.v, x.vd))
        a = s.total([s.mul(x.v, y.a), s.mul(2.0, s.mul(x.vd, y.vd)), s.mul(y.v, x.a)])
        return Jet(s.mul(x.v, y.v), g, vd, a)


def sincos(x: Jet) -> tuple[Jet, Jet]:
    """(sin x, cos x) as jets, sharing one evaluation of each transcendental."""
    if s.is_const(x.v):
        import math

        return Jet(math.sin(x.v)), Jet(math.cos(x.v))
    sv, cv = jnp.sin(x.v), jnp.cos(x.v)
    vd2 = s.mul(x.vd, x.vd)
    sin = Jet(
        sv,
        {j: s.mul(cv, d) for j, d in x.g.items()},
        s.mul(cv, x.vd),
        s.sub(s.mul(cv, x.a), s.mul(sv, vd2)),
    )
    cos = Jet(
        cv,
        {j: s.neg(s.mul(sv, d)) for j, d in x.g.items()},
        s.neg(s.mul(sv, x.vd)),
        s.neg(s.add(s.mul(sv, x.a), s.mul(cv, vd2))),
    )
    return sin, cos
