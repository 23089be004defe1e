"""Planar kinematics as sums of unit vectors, differentiated and dotted at trace time.

Every point of a planar chain is a sum of terms ``c * u(phi_a)`` where ``u`` is ``d`` or ``e``
(see :mod:`lagrange.chain`), ``phi_a`` is the absolute angle of revolute joint ``a`` (or the
base), and ``c`` a length, or a prismatic coordinate times a length. The rules

- ``d/dphi d = e``, ``d/dphi e = -d`` (so ``d2/dphi2 u = -u``),
- ``d(a).d(b) = e(a).e(b) = cos(phi_a - phi_b)``, ``d(a).e(b) = sin(phi_a - phi_b)``,
  ``u(a).u(a) = 1``, ``d(a).e(a) = 0``,

give the centre-of-mass Jacobian columns ``J_ij`` and velocity-product accelerations
``(dJ_i/dt) qd`` as such sums, and their dot products in terms of the *relative* angles between
links, with ``|u|^2 = 1`` and ``d.e = 0`` folded before anything is traced. For a short chain
this is exactly the program a person writes by hand for ``M`` and ``C qd + T`` (the acrobot
needs sin/cos of q2, sin q1 and sin(q1 + q2), nothing else). It needs sin/cos of every pair of
link angles, O(n^2) transcendentals, so long chains use the jets of :mod:`lagrange._jet`.
"""

from __future__ import annotations

from lagrange import _scalar as s
from lagrange.chain import Chain

BASE = -1


class Geometry:
    """Trace-time description of a chain's kinematics plus cached trigonometry of ``q``."""

    def __init__(self, chain: Chain, q, qd):
        import math

        import jax.numpy as jnp

        self._jnp = jnp
        n = chain.n
        self.n = n
        self.q = [q[..., i] for i in range(n)]
        self.qd = None if qd is None else [qd[..., i] for i in range(n)]
        # angle index of each link: last revolute joint <= i, or BASE
        ang, revs, a = [], {BASE: ()}, BASE
        for i, joint in enumerate(chain.joints):
            if joint == "revolute":
                revs[i] = revs[a] + (i,)
                a = i
            ang.append(a)
        self.ang, self.revs = ang, revs
        self._trig: dict = {}
        # positions of every centre of mass: lists of (coef, qk, kind, angle)
        terms: list = []
        coms = []
        for i, joint in enumerate(chain.joints):
            parent = ang[i - 1] if i > 0 else BASE
            if i > 0:
                terms = terms + [(chain.length[i - 1], None, "d", parent)]
            if joint == "prismatic":
                ax = chain.axes[i]
                if ax == 0.0:
                    terms = terms + [(1.0, i, "e", parent)]
                else:
                    terms = terms + [(math.cos(ax), i, "e", parent), (-math.sin(ax), i, "d", parent)]
            coms.append(terms + [(chain.com[i], None, "d", ang[i])])
        self.coms = coms

    # -- trigonometry ---------------------------------------------------------------------
    def _angle_sum(self, joints):
        return s.total(self.q[j] for j in joints)

    def trig_abs(self, a):
        """(sin phi_a, cos phi_a)."""
        if a == BASE:
            return 0.0, 1.0
        key = ("abs", a)
        if key not in self._trig:
            x = self._angle_sum(self.revs[a])
            self._trig[key] = (self._jnp.sin(x), self._jnp.cos(x))
        return self._trig[key]

    def trig_rel(self, a, b):
        """(sin(phi_a - phi_b), cos(phi_a - phi_b))."""
        if a == b:
            return 0.0, 1.0
        hi, lo, sign = (a, b, 1.0) if a > b else (b, a, -1.0)
        if lo == BASE:
            sn, cs = self.trig_abs(hi)
        else:
            key = ("rel", hi, lo)
            if key not in self._trig:
                x = self._angle_sum([j for j in self.revs[hi] if j > lo])
                self._trig[key] = (self._jnp.sin(x), self._jnp.cos(x))
            sn, cs = self._trig[key]
        return s.mul(sign, sn), cs

    def unit_dot(self, k1, a1, k2, a2):
        if a1 == a2:
            return 1.0 if k1 == k2 else 0.0
        sn, cs = self.trig_rel(a1, a2)
        if k1 == k2:
            return cs
        return sn if k1 == "d" else s.neg(sn)

    def unit_z(self, kind, a):
        sn, cs = self.trig_abs(a)
        return s.neg(cs) if kind == "d" else sn

    # -- derivatives ----------------------------------------------------------------------
    def _coef(self, c, qk):
        return c if qk is None else s.mul(c, self.q[qk])

    def jacobian_column(self, i, j):
        """d c_i / d q_j as {(kind, angle): coef}."""
        out: dict = {}
        rev_j = j if j in self.revs else None
        for c, qk, kind, a in self.coms[i]:
            if qk == j:
                _acc(out, (kind, a), c)
            if rev_j is not None and j in self.revs[a]:
                if kind == "d":
                    _acc(out, ("e", a), self._coef(c, qk))
                else:
                    _acc(out, ("d", a), s.neg(self._coef(c, qk)))
        return out

    def rate(self, a):
        return s.total(self.qd[j] for j in self.revs[a])

    def bias_acceleration(self, i):
        """(dJ_i/dt) qd, the acceleration of c_i at zero joint acceleration."""
        out: dict = {}
        for c, qk, kind, a in self.coms[i]:
            w = self.rate(a)
            if not s.is_zero(w):
                _acc(out, (kind, a), s.neg(s.mul(self._coef(c, qk), s.mul(w, w))))
                if qk is not None:
                    t = s.mul(s.mul(2.0, c), s.mul(self.qd[qk], w))
                    if kind == "d":
                        _acc(out, ("e", a), t)
                    else:
                        _acc(out, ("d", a), s.neg(t))
        return out

    def dot(self, x: dict, y: dict, scale=1.0):
        """scale * (x . y), multiplying the coefficients (often parameters only) first."""
        return s.total(
            s.mul(s.mul(s.mul(scale, cx), cy), self.unit_dot(kx, ax, ky, ay))
            for (kx, ax), cx in x.items()
            for (ky, ay), cy in y.items()
        )

    def z(self, x: dict, scale=1.0):
        """scale * (x . e_z)."""
        return s.total(s.mul(s.mul(scale, c), self.unit_z(k, a)) for (k, a), c in x.items())


def _acc(d: dict, key, value):
    d[key] = s.add(d.get(key, 0.0), value)


def mass_entries(chain: Chain, geom: Geometry) -> list[list]:
    n = chain.n
    M = [[0.0] * n for _ in range(n)]
    for i in range(n):
        cols = {j: geom.jacobian_column(i, j) for j in range(i + 1)}
        cols = {j: c for j, c in cols.items() if c}
        m = chain.mass[i]
        keys = sorted(cols)
        for a, j in enumerate(keys):
            for k in keys[: a + 1]:
                M[max(j, k)][min(j, k)] = s.add(M[max(j, k)][min(j, k)], geom.dot(cols[j], cols[k], m))
        rev = geom.revs[geom.ang[i]]
        for a, j in enumerate(rev):
            for k in rev[: a + 1]:
                M[max(j, k)][min(j, k)] = s.add(M[max(j, k)][min(j, k)], chain.inertia[i])
    for j in chain.armatured:
        M[j][j] = s.add(M[j][j], chain.armature[j])
    return M


def generalized_forces(chain: Chain, geom: Geometry, *, velocity: bool, gravity: bool) -> list:
    """sum_i m_i J_i^T (a_i + g e_z): velocity-product and gravity generalized forces."""
    n = chain.n
    out = [0.0] * n
    g = chain.gravity if (gravity and chain.gravity is not None) else 0.0
    for i in range(n):
        acc = geom.bias_acceleration(i) if velocity else {}
        m = chain.mass[i]
        for j in range(i + 1):
            col = geom.jacobian_column(i, j)
            if not col:
                continue
            out[j] = s.add(out[j], s.add(geom.dot(col, acc, m), geom.z(col, s.mul(m, g))))
    return out
