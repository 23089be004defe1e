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
link angles, O(n^2) transcendentals, so long chains use :mod:`lagrange.planar.recursive` (see
``lagrange.dynamics.RECURSIVE_MIN``).
"""

from __future__ import annotations

import math

from lagrange.math import scalar as s
from lagrange.math.scalar import cos_sin
from lagrange.planar.model import WORLD, PlanarChain

BASE = -1


class _Symbol:
    """A placeholder run-time value for the structure-only dry run of :func:`plan`."""

    def _same(self, *_):
        return self

    __add__ = __radd__ = __sub__ = __rsub__ = __mul__ = __rmul__ = _same
    __truediv__ = __rtruediv__ = __neg__ = __getitem__ = _same


SYMBOL = _Symbol()


class _StructureOnly:
    """A chain's static structure with every parameter replaced by :data:`SYMBOL`."""

    def __init__(self, chain: PlanarChain):
        self.joints, self.axes, self.n = chain.joints, chain.axes, chain.n
        self.parents, self.attached, self.senses = chain.parents, chain.attached, chain.senses
        self.frame_offsets = chain.frame_offsets
        self.armatured, self.damped = chain.armatured, chain.damped
        self.com_normal = None if chain.com_normal is None else SYMBOL
        self.mass = self.length = self.com = self.inertia = SYMBOL
        self.armature = None if chain.armature is None else SYMBOL
        self.gravity = None if chain.gravity is None else SYMBOL
        self.attach = None if chain.attach is None else SYMBOL


class Geometry:
    """Trace-time description of a chain's kinematics plus cached trigonometry of ``q``.

    ``absolute`` names the link angles whose absolute sin/cos the computation needs anyway
    (from :func:`plan`); relative-angle trig between two of them is then formed by products
    (``cos(a - b) = cos a cos b + sin a sin b``) instead of two more transcendentals.
    """

    def __init__(self, chain: PlanarChain, q, qd, absolute=frozenset()):

        import jax.numpy as jnp

        self._jnp = jnp
        n = chain.n
        self.n = n
        self.absolute = absolute
        self.requested: set = set()
        if q is SYMBOL:
            self.q = [SYMBOL] * n
            self.qd = None if qd is None else [SYMBOL] * n
        else:
            self.q = [q[..., i] for i in range(n)]
            self.qd = None if qd is None else [qd[..., i] for i in range(n)]
        # angle index of each link: the last revolute joint on its path from the world (itself included), or BASE
        ang, revs = [], {BASE: ()}
        for i, joint in enumerate(chain.joints):
            a = BASE if chain.parents[i] == WORLD else ang[chain.parents[i]]
            if joint == "revolute":
                revs[i] = revs[a] + (i,)
                a = i
            ang.append(a)
        self.ang, self.revs = ang, revs
        self.flipped = frozenset(i for i, sense in enumerate(chain.senses) if sense < 0)
        self._trig: dict = {}
        # positions of every joint origin and centre of mass: lists of (coef, qk, kind, angle). A link's frame is at
        # phi_a + off (a: its angle variable, off: the static sum of the frame offsets), so a vector c_d d + c_e e of
        # the link's frame is (c_d cos off - c_e sin off) d(phi_a) + (c_d sin off + c_e cos off) e(phi_a).
        off = chain.frame_offsets()
        normal = chain.com_normal
        attach = {i: k for k, i in enumerate(chain.attached)}
        origins: list = []
        coms = []
        for i, joint in enumerate(chain.joints):
            p = chain.parents[i]
            terms = [] if p == WORLD else origins[p]
            parent = BASE if p == WORLD else ang[p]
            parent_off = 0.0 if p == WORLD else off[p]
            if i in attach:  # (x, z) in the parent's frame: -z along d, x along e
                point = chain.attach[attach[i]]
                terms = terms + _rotated(s.neg(point[1]), point[0], parent_off, parent)
            elif p != WORLD:
                terms = terms + _rotated(chain.length[p], None, parent_off, parent)
            if joint == "prismatic":
                ax = chain.axes[i] + parent_off
                if ax == 0.0:
                    terms = terms + [(1.0, i, "e", parent)]
                else:
                    terms = terms + [(math.cos(ax), i, "e", parent), (-math.sin(ax), i, "d", parent)]
            origins.append(terms)
            coms.append(terms + _rotated(chain.com[i], None if normal is None else normal[i], off[i], ang[i]))
        self.coms = coms

    # -- trigonometry ---------------------------------------------------------------------
    def _angle_sum(self, joints):
        """``sum_j sense_j q_j``."""
        return s.total(s.negated(self.q[j]) if j in self.flipped else self.q[j] for j in joints)

    def _sincos(self, x):
        """(sin x, cos x), each traced only when first used."""
        negative, x = s.sign_and_magnitude(x)  # sin(-x) = -sin x, cos(-x) = cos x
        if x is SYMBOL:
            return SYMBOL, SYMBOL
        return _Lazy(self._jnp.sin, x, negative), _Lazy(self._jnp.cos, x)

    def _abs(self, a):
        if a == BASE:
            return 0.0, 1.0
        key = ("abs", a)
        if key not in self._trig:
            self._trig[key] = self._sincos(self._angle_sum(self.revs[a]))
        return self._trig[key]

    def sin_abs(self, a):
        self.requested.add(("sin", a))
        return _force(self._abs(a)[0])

    def cos_abs(self, a):
        self.requested.add(("cos", a))
        return _force(self._abs(a)[1])

    def _have_abs(self, a):
        return ("sin", a) in self.absolute and ("cos", a) in self.absolute

    def _rel(self, hi, lo, which: int):
        """sin (which=0) or cos (which=1) of phi_hi - phi_lo for hi > lo > BASE."""
        key = ("rel", hi, lo)
        if key not in self._trig:
            if self._have_abs(hi) and self._have_abs(lo):
                (sh, ch), (sl, cl) = [tuple(map(_force, self._abs(a))) for a in (hi, lo)]
                self._trig[key] = (s.sub(s.mul(sh, cl), s.mul(ch, sl)), s.add(s.mul(ch, cl), s.mul(sh, sl)))
            else:
                self._trig[key] = self._sincos(self._angle_difference(hi, lo))
        return _force(self._trig[key][which])

    def _angle_difference(self, hi, lo):
        """``phi_hi - phi_lo``: the revolute joints on ``hi``'s path and not ``lo``'s, less those on ``lo``'s and not
        ``hi``'s (none when ``lo`` is on ``hi``'s path, as in a serial chain)."""
        mine, theirs = self.revs[hi], set(self.revs[lo])
        ahead = self._angle_sum([j for j in mine if j not in theirs])
        behind = [j for j in self.revs[lo] if j not in set(mine)]
        return ahead if not behind else s.sub(ahead, self._angle_sum(behind))

    def rel_sin(self, a, b):
        """sin(phi_a - phi_b)."""
        if a == b:
            return 0.0
        if b == BASE:
            return self.sin_abs(a)
        if a == BASE:
            return s.negated(self.sin_abs(b))
        return self._rel(a, b, 0) if a > b else s.negated(self._rel(b, a, 0))

    def rel_cos(self, a, b):
        """cos(phi_a - phi_b)."""
        if a == b:
            return 1.0
        if BASE in (a, b):
            return self.cos_abs(a if b == BASE else b)
        return self._rel(max(a, b), min(a, b), 1)

    def unit_dot(self, k1, a1, k2, a2):
        if a1 == a2:
            return 1.0 if k1 == k2 else 0.0
        if k1 == k2:
            return self.rel_cos(a1, a2)
        sn = self.rel_sin(a1, a2)
        return sn if k1 == "d" else s.negated(sn)

    def unit_z(self, kind, a):
        return s.negated(self.cos_abs(a)) if kind == "d" else self.sin_abs(a)

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
            if rev_j is not None and j in self.revs[a]:  # d/dphi d = e, d/dphi e = -d; dphi/dq_j = sense_j
                flip = j in self.flipped
                if (kind == "d") != flip:
                    _acc(out, ("e" if kind == "d" else "d", a), self._coef(c, qk))
                else:
                    _acc(out, ("e" if kind == "d" else "d", a), s.negated(self._coef(c, qk)))
        return out

    def rate(self, a):
        """``d phi_a / dt = sum_j sense_j qd_j``."""
        return s.total(s.negated(self.qd[j]) if j in self.flipped else self.qd[j] for j in self.revs[a])

    def bias_acceleration(self, i):
        """(dJ_i/dt) qd, the acceleration of c_i at zero joint acceleration."""
        out: dict = {}
        for c, qk, kind, a in self.coms[i]:
            w = self.rate(a)
            if not s.is_zero(w):
                _acc(out, (kind, a), s.negated(s.mul(self._coef(c, qk), s.mul(w, w))))
                if qk is not None:
                    t = s.mul(s.mul(2.0, c), s.mul(self.qd[qk], w))
                    if kind == "d":
                        _acc(out, ("e", a), t)
                    else:
                        _acc(out, ("d", a), s.negated(t))
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


def _rotated(c_d, c_e, off: float, a) -> list:
    """Terms of ``c_d d(phi_a + off) + c_e e(phi_a + off)`` (``c_e = None``: none) on ``d(phi_a)``, ``e(phi_a)``."""
    if off == 0.0:
        return [(c_d, None, "d", a)] + ([] if c_e is None else [(c_e, None, "e", a)])
    co, so = cos_sin(off)
    if so == 0.0:
        return _rotated(s.mul(co, c_d), None if c_e is None else s.mul(co, c_e), 0.0, a)
    if co == 0.0:
        return _rotated(s.negated(s.mul(so, c_e)) if c_e is not None else 0.0, s.mul(so, c_d), 0.0, a)
    if c_e is None:
        return [(s.mul(co, c_d), None, "d", a), (s.mul(so, c_d), None, "e", a)]
    return [
        (s.sub(s.mul(co, c_d), s.mul(so, c_e)), None, "d", a),
        (s.add(s.mul(so, c_d), s.mul(co, c_e)), None, "e", a),
    ]


class _Lazy:
    """``fn(x)`` (``-fn(x)``, the sign kept symbolic, if ``negate``), traced on first use and then reused."""

    def __init__(self, fn, x, negate: bool = False):
        self.fn, self.x, self.negate, self.value = fn, x, negate, None


def _force(v):
    if isinstance(v, _Lazy):
        if v.value is None:
            v.value = v.fn(v.x)
        return s.negated(v.value) if v.negate else v.value
    return v


def plan(chain: PlanarChain, *, mass: bool, velocity: bool, gravity: bool) -> frozenset:
    """The ("sin"|"cos", angle) values the requested terms need anyway, by a dry run on structure."""
    proxy = _StructureOnly(chain)
    geom = Geometry(proxy, SYMBOL, SYMBOL if velocity else None)
    if mass:
        mass_entries(proxy, geom)
    if velocity or gravity:
        generalized_forces(proxy, geom, velocity=velocity, gravity=gravity)
    return frozenset(geom.requested)


def _acc(d: dict, key, value):
    d[key] = s.add(d.get(key, 0.0), value)


def mass_entries(chain: PlanarChain, geom: Geometry) -> list[list]:
    """Lower triangle of the translational part of M, ``sum_i m_i J_i^T J_i``."""
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
    return M


def generalized_forces(chain: PlanarChain, geom: Geometry, *, velocity: bool, gravity: bool) -> list:
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
