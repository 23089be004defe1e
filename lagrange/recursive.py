"""Recursive dynamics of long planar chains: ABA, RNEA and CRBA on planar spatial vectors.

The trace-time derivations of :mod:`lagrange.dynamics` write out every entry of ``M`` and solve
``M qdd = rhs`` by elimination, so their work and their compiled program grow like n^3. Here the
same equations are evaluated by Featherstone's recursive algorithms, with every per-link
quantity held in arrays whose leading axis runs over the links: the compiled program has the
same size for every n and the work is O(n) (forward dynamics, bias and gravity forces) or
O(n^2) (the mass matrix).

Planar spatial algebra. A *motion* ``(w, vx, vz)`` is an angular velocity ``w = dphi/dt`` and
the velocity of the body point at a reference point; a *force* ``(t, Fx, Fz)`` is a moment about
that point and a force. With ``perp(x, z) = (-z, x)`` (so ``d/dt d(phi) = w perp(d(phi))``) and
``cross(a, b) = a_x b_z - a_z b_x``:

- moving the reference point by ``r`` (``p_new = p_old + r``): a motion becomes
  ``(w, v + w perp(r))`` (the matrix ``X(r)``), a force given at ``p_new`` becomes
  ``(t + perp(r).F, F)`` at ``p_old`` (``X(r)^T``);
- ``m1 x m2 = (0, w1 perp(v2) - w2 perp(v1))`` and ``m x* f = (cross(v, F), w perp(F))``;
- a body of mass ``m``, centre of mass at ``c`` from the reference point and inertia ``I``
  about it has the spatial inertia ``[[I + m|c|^2, m perp(c)^T], [m perp(c), m 1]]``.

Body i's reference point is its joint origin ``p_i`` and every frame keeps the world's axes, so
``X_i = X(r_i)`` with ``r_i = p_i - p_{i-1} = l_{i-1} d(phi_{i-1}) [+ q_i e(phi_{i-1} + axis_i)]``
and the joint's motion subspace is ``S_i = (1, 0, 0)`` (revolute) or ``(0, e(phi_{i-1} + axis_i))``
(prismatic). Gravity enters as the base acceleration ``a_0 = (0, 0, g)``. Then

- kinematics: ``v_i = X_i v_{i-1} + S_i qd_i`` and ``c_i = v_i x S_i qd_i``, with the link angles, their
  sines and cosines and the joint offsets ``r_i``: one ``jax.lax.scan`` outward over the links;
- RNEA: ``a_i = X_i a_{i-1} + S_i qdd_i + c_i``, ``f_i = I_i a_i + v_i x* I_i v_i``,
  ``tau_i = S_i . sum_{k >= i} X_{i<-k}^T f_k`` (cumulative sums again);
- CRBA: composite inertias ``Ic_i = I_i + X_{i+1}^T Ic_{i+1} X_{i+1}`` (cumulative sums of
  mass, first and second moments), ``M_ij = S_j . X_{j<-i}^T Ic_i S_i`` for ``j <= i``;
- ABA: inward, ``IA_i = I_i + X_{i+1}^T Ia_{i+1} X_{i+1}``, ``pA_i = v_i x* I_i v_i +
  X_{i+1}^T pa_{i+1}``, ``U_i = IA_i S_i``, ``D_i = S_i . U_i + armature_i``,
  ``u_i = tau_i - S_i . pA_i``, ``Ia_i = IA_i - U_i U_i^T / D_i``,
  ``pa_i = pA_i + Ia_i c_i + U_i u_i / D_i``; outward, ``a'_i = X_i a_{i-1} + c_i``,
  ``qdd_i = (u_i - U_i . a'_i) / D_i``, ``a_i = a'_i + S_i qdd_i``. The two passes are
  ``jax.lax.scan`` over the links, each step's inputs and outputs separate arrays of the batch's
  shape. Armature and an implicit-damping term ``h damping_i`` add to ``D_i``, which is adding them
  to ``M_ii``.

Functions take ``q``/``qd``/``u`` with any leading batch dimensions (broadcast against each
other) and return the same quantities as :mod:`lagrange.dynamics`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from lagrange import _scalar as s
from lagrange import _unitvec
from lagrange._sincos import sincos
from lagrange.chain import Chain


# ------------------------------------------------------------------ link-axis helpers


def _links_first(x, batch):
    """(..., n) -> (n, *batch), broadcast to the batch shape."""
    x = jnp.broadcast_to(x, batch + x.shape[-1:])
    return jnp.moveaxis(x, -1, 0)


def _param(x, nb: int):
    """A per-link parameter (n,) shaped (n, 1, ..., 1) to broadcast against (n, *batch)."""
    return jnp.reshape(x, x.shape + (1,) * nb)


def _prev(x, first):
    """x shifted one link outward: ``out[0] = first``, ``out[i] = x[i - 1]``."""
    if s.is_const(x):  # a structural zero (no revolute joint)
        return x
    return jnp.concatenate([jnp.full_like(x[:1], first), x[:-1]], axis=0)


def _next(x):
    """x shifted one link inward: ``out[i] = x[i + 1]``, ``out[n - 1] = 0``."""
    return jnp.concatenate([x[1:], jnp.zeros_like(x[:1])], axis=0)


def _cumsum(x):
    if s.is_const(x):  # a structural zero
        return x
    return jnp.cumsum(x, axis=0)


def _rcumsum(x):
    """sum_{k >= i} x_k."""
    return jnp.flip(jnp.cumsum(jnp.flip(x, 0), axis=0), 0)


def _batch(*xs):
    return jnp.broadcast_shapes(*(jnp.shape(x)[:-1] for x in xs if x is not None))


def _dtype(chain: Chain, *xs):
    return jnp.result_type(chain.mass, *(x for x in xs if x is not None))


# ------------------------------------------------------------------ kinematics


def _per_link(x, dtype):
    """A per-link parameter for a scan over the links: a Python float when every link has the same concrete value (it
    folds into the compiled step), else an array of shape (n,) that the scan slices link by link."""
    if isinstance(x, np.ndarray) and x.size and np.all(x == x.flat[0]):
        return float(x.flat[0])
    return jnp.asarray(x, dtype)


class _Kin:
    """Per-link kinematics, every array shaped (n, *batch) (or a Python float when static).

    ``S``: the joint axes; ``r``: ``p_i - p_{i-1}``; ``sin``/``cos``: of phi_i; ``w``, ``v``: the
    spatial velocity at ``p_i``; ``c``: ``v_i x S_i qd_i`` (linear part; its angular part is 0);
    ``m``, ``h``, ``J``: mass, first moment ``m com d(phi_i)`` and inertia about ``p_i``;
    ``pA``: ``v_i x* I_i v_i``. Velocity terms are ``None`` when ``qd`` is.

    Computed by one ``lax.scan`` outward over the links (:func:`_scan`): each step is a few dozen multiplies on
    arrays of the batch's shape, which XLA's CPU backend vectorises, where cumulative sums over the link axis
    (``reduce_window``) cost several times more. The link angles' sines and cosines come from the angle-addition
    formulas on the joint angles' (one :func:`sincos` of every joint before the scan): a polynomial sine inside the
    step cost two kernels per link (one per output, each evaluating both polynomials), 10% of the forward step at
    n = 32. Against the exact sines of the summed angles the errors are <= 1.3e-15 at n = 32 and 1.9e-15 at n = 64
    (``tests/lagrange/test_recursive.py``).
    """

    def __init__(self, chain: Chain, q, qd, nb: int):
        dtype = q.dtype
        n = chain.n
        rev = np.array([j == "revolute" for j in chain.joints])
        off = np.asarray(chain.frame_offsets(), float)
        poff = np.concatenate([[0.0], off[:-1]])  # the parent frame's offset
        L = lambda x: _per_link(x, dtype)  # noqa: E731
        lp = chain.length  # the parent's length, 0 for the first link
        if isinstance(lp, np.ndarray):
            lp = np.concatenate([[0.0], lp[:-1]])
        else:
            lp = jnp.concatenate([jnp.zeros((1,), lp.dtype), lp[:-1]])
        cs_p = np.array([_unitvec.cos_sin(o) for o in poff]).reshape(n, 2)
        # the joint angles' sines and cosines, every link at once (a prismatic joint's: 0 and 1)
        sq, cq = sincos(q if rev.all() else q * _param(jnp.asarray(rev, dtype), nb))
        xs = dict(sq=sq, cq=cq) | ({} if rev.all() else dict(q=q))
        params = dict(ld=lp * cs_p[:, 0], le=lp * cs_p[:, 1])
        if not rev.all():
            axes = np.asarray(chain.axes) + poff
            params |= dict(rev=rev.astype(float), pri=(~rev).astype(float), ca=np.cos(axes), sa=np.sin(axes))
        m, com = chain.mass, chain.com
        cs = np.array([_unitvec.cos_sin(o) for o in off]).reshape(n, 2)
        cn = 0.0 if chain.com_normal is None else chain.com_normal
        # the centre of mass c_d d(phi + off) + c_e e(phi + off), on d(phi) and e(phi)
        cd, ce = com * cs[:, 0] - cn * cs[:, 1], com * cs[:, 1] + cn * cs[:, 0]
        params |= dict(mcd=m * cd, mce=m * ce)
        J = chain.inertia + m * (com * com + cn * cn)
        self.m, self.J = (v if isinstance(v, float) else _param(v, nb) for v in (L(m), L(J)))
        if qd is not None:
            xs["qd"] = qd
            params |= dict(m=m, J=J)
        consts = {}
        for key, v in params.items():
            v = L(v)
            if isinstance(v, float):
                consts[key] = v
            else:
                xs[key] = v
        batch = q.shape[1:]
        zero = jnp.zeros(batch, dtype)

        def step(carry, x):
            x = {**consts, **x}
            sp, cp = carry[:2]
            qi = x.get("q")
            # phi_i = phi_{i-1} + q_i (revolute): the angle-addition formulas on the joint angle's sine and cosine
            sin = s.add(s.mul(sp, x["cq"]), s.mul(cp, x["sq"]))
            cos = s.sub(s.mul(cp, x["cq"]), s.mul(sp, x["sq"]))
            # the parent's tip l d(phi + off) = l cos(off) d(phi) + l sin(off) e(phi), d = (sin, -cos), e = (cos, sin)
            ld, le = x["ld"], x["le"]
            rx = s.add(s.mul(ld, sp), s.mul(le, cp))
            rz = s.add(s.mul(s.neg(ld), cp), s.mul(le, sp))
            if "pri" in x:  # e(phi_{i-1} + axis_i) = cos a e(phi) - sin a d(phi)
                ex = s.sub(s.mul(x["ca"], cp), s.mul(x["sa"], sp))
                ez = s.add(s.mul(x["ca"], sp), s.mul(x["sa"], cp))
                S = (x["rev"], s.mul(x["pri"], ex), s.mul(x["pri"], ez))
                rx, rz = s.add(rx, s.mul(S[1], qi)), s.add(rz, s.mul(S[2], qi))
            else:
                S = (1.0, 0.0, 0.0)
            hx = s.add(s.mul(x["mcd"], sin), s.mul(x["mce"], cos))
            hz = s.sub(s.mul(x["mce"], sin), s.mul(x["mcd"], cos))
            out = dict(sin=sin, cos=cos, rx=rx, rz=rz, hx=hx, hz=hz)
            if not isinstance(S[1], float):
                out |= dict(s0=S[0], s1=S[1], s2=S[2])
            if qd is None:
                return (sin, cos), _arrays(out, zero)
            w, vx, vz = carry[2:]
            qdi = x["qd"]
            sw, svx, svz = s.mul(S[0], qdi), s.mul(S[1], qdi), s.mul(S[2], qdi)
            vx = s.add(s.add(vx, s.mul(s.neg(w), rz)), svx)
            vz = s.add(s.add(vz, s.mul(w, rx)), svz)
            w = s.add(w, sw)
            # c = v x (S qd) = (0, w perp(sv) - sw perp(v))
            cx = s.add(s.neg(s.mul(w, svz)), s.mul(sw, vz))
            cz = s.sub(s.mul(w, svx), s.mul(sw, vx))
            t, Fx, Fz = _momentum(x["J"], hx, hz, x["m"], w, vx, vz)
            out |= dict(w=w, vx=vx, vz=vz, cx=cx, cz=cz,
                        pt=s.sub(s.mul(vx, Fz), s.mul(vz, Fx)), px=s.neg(s.mul(w, Fz)), pz=s.mul(w, Fx))
            return (sin, cos) + _arrays((w, vx, vz), zero), _arrays(out, zero)

        init = (zero, zero + 1.0) + ((zero, zero, zero) if qd is not None else ())
        _, ys = _scan(step, init, xs)
        self.sin, self.cos, self.rx, self.rz, self.hx, self.hz = (ys[k] for k in ("sin", "cos", "rx", "rz", "hx", "hz"))
        self.S = (ys["s0"], ys["s1"], ys["s2"]) if "s0" in ys else (1.0, 0.0, 0.0)
        self.w = self.vx = self.vz = self.cx = self.cz = self.pA = None
        if qd is not None:
            self.w, self.vx, self.vz, self.cx, self.cz = (ys[k] for k in ("w", "vx", "vz", "cx", "cz"))
            self.pA = (ys["pt"], ys["px"], ys["pz"])

    def momentum(self, w, vx, vz):
        """``I_i (w, vx, vz)``: the spatial inertia times a motion."""
        return _momentum(self.J, self.hx, self.hz, self.m, w, vx, vz)


def _arrays(xs, like):
    """``xs`` (a dict or tuple) with every entry an array shaped like ``like`` (scan outputs and carries)."""
    if isinstance(xs, dict):
        return {key: jnp.broadcast_to(jnp.asarray(v, like.dtype), like.shape) for key, v in xs.items()}
    return tuple(jnp.broadcast_to(jnp.asarray(v, like.dtype), like.shape) for v in xs)


def _momentum(J, hx, hz, m, w, vx, vz):
    """``I (w, vx, vz)`` for the spatial inertia of mass ``m``, first moment ``(hx, hz)`` and inertia ``J`` about the
    reference point."""
    return (
        s.add(s.sub(s.mul(J, w), s.mul(hz, vx)), s.mul(hx, vz)),
        s.sub(s.mul(m, vx), s.mul(hz, w)),
        s.add(s.mul(hx, w), s.mul(m, vz)),
    )


def clamp_controls(chain: Chain, u):
    """``u`` (shape ``(..., m)``) with each control clamped into its joint's ``control_range``, as MuJoCo clamps a
    limited ``ctrl``; ``u`` itself for a chain without ranges."""
    if chain.control_ranges is None:
        return u
    inf = float("inf")
    lo = np.array([-inf if r is None else r[0] for r in chain.control_ranges])
    hi = np.array([inf if r is None else r[1] for r in chain.control_ranges])
    return jnp.clip(u, lo.astype(u.dtype), hi.astype(u.dtype))


def _actuation(chain: Chain, u, batch, dtype):
    """``B u`` as (n, *batch), or None without control."""
    if u is None or chain.m == 0:
        return None
    u = clamp_controls(chain, jnp.asarray(u))
    u = jnp.moveaxis(jnp.broadcast_to(u, batch + u.shape[-1:]), -1, 0)
    gu = _param(chain.gear, len(batch)).astype(dtype) * u
    if chain.actuated == tuple(range(chain.n)):
        return gu
    select = np.zeros((chain.n, chain.m))  # B / gear: a 0/1 matrix (a dot, not a scatter)
    select[list(chain.actuated), range(chain.m)] = 1.0
    return jnp.tensordot(jnp.asarray(select, dtype), gu, axes=1)


def _out(x):
    """(n, *batch) -> (*batch, n)."""
    return jnp.moveaxis(x, 0, -1)


# ------------------------------------------------------------------ RNEA


def _rnea(chain: Chain, k: _Kin, qdd, gravity: bool):
    """``S_i . (sum_{k >= i} X^T f_k)`` for ``f = I a + v x* I v``, shape (n, *batch)."""
    g = chain.gravity if (gravity and chain.gravity is not None) else 0.0
    S = k.S
    cx = 0.0 if k.cx is None else k.cx
    cz = 0.0 if k.cz is None else k.cz
    if qdd is None:  # a_i = a_0 + sum_{k <= i} c_k (c has no angular part)
        al = 0.0
        ax = 0.0 if s.is_const(cx) else _cumsum(cx)
        az = 0.0 if s.is_const(cz) else _cumsum(cz)
    else:
        al = _cumsum(s.mul(S[0], qdd))
        ap = _prev(al, 0.0)
        ax = _cumsum(s.add(s.add(s.mul(s.neg(ap), k.rz), s.mul(S[1], qdd)), cx))
        az = _cumsum(s.add(s.add(s.mul(ap, k.rx), s.mul(S[2], qdd)), cz))
    az = s.add(az, g)
    t, Fx, Fz = k.momentum(al, ax, az)
    if k.pA is not None:
        t, Fx, Fz = t + k.pA[0], Fx + k.pA[1], Fz + k.pA[2]
    like = k.sin
    t, Fx, Fz = (jnp.broadcast_to(x, like.shape) for x in (t, Fx, Fz))
    Fx, Fz = _rcumsum(Fx), _rcumsum(Fz)
    # moments about p_i: t_i + perp(r_{i+1}) . Ftot_{i+1} + (the same for the links beyond)
    t = _rcumsum(t - _next(k.rz) * _next(Fx) + _next(k.rx) * _next(Fz))
    return s.add(s.add(s.mul(S[0], t), s.mul(S[1], Fx)), s.mul(S[2], Fz))


def _prepare(chain: Chain, q, qd, *extra):
    batch = _batch(q, qd, *extra)
    dtype = _dtype(chain, q, qd, *extra)
    q = _links_first(q.astype(dtype), batch)
    qd = None if qd is None else _links_first(qd.astype(dtype), batch)
    return batch, dtype, q, qd


def _damping(chain: Chain, qd):
    return None if chain.damping is None else _param(chain.damping, qd.ndim - 1) * qd


def bias_forces(chain: Chain, q, qd):
    """``C(q, qd) qd + T(q) + D qd`` by RNEA at ``qdd = 0``, shape (..., n)."""
    batch, _, q, qd = _prepare(chain, q, qd)
    k = _Kin(chain, q, qd, len(batch))
    f = _rnea(chain, k, None, gravity=True)
    if chain.damping is not None:
        f = f + _damping(chain, qd)
    return _out(f)


def gravity_forces(chain: Chain, q):
    """``T(q) = dV/dq`` by RNEA at rest, shape (..., n)."""
    batch, _, q, _ = _prepare(chain, q, None)
    if chain.gravity is None:
        return jnp.zeros(batch + (chain.n,), q.dtype)
    return _out(_rnea(chain, _Kin(chain, q, None, len(batch)), None, gravity=True))


def inverse_dynamics(chain: Chain, q, qd, qdd):
    """``M qdd + C qd + T + D qd`` by RNEA, shape (..., n)."""
    batch, dtype, q, qd = _prepare(chain, q, qd, qdd)
    qdd = _links_first(qdd.astype(dtype), batch)
    k = _Kin(chain, q, qd, len(batch))
    f = _rnea(chain, k, qdd, gravity=True)
    if chain.damping is not None:
        f = f + _damping(chain, qd)
    if chain.armature is not None:
        f = f + _param(chain.armature, len(batch)) * qdd
    return _out(f)


# ------------------------------------------------------------------ CRBA


def mass_matrix(chain: Chain, q):
    """``M(q)`` by the composite-rigid-body algorithm, shape (..., n, n); O(n^2) work."""
    batch, _, q, _ = _prepare(chain, q, None)
    k = _Kin(chain, q, None, len(batch))
    m = jnp.broadcast_to(k.m, q.shape)
    rx, rz = _next(k.rx), _next(k.rz)
    mc = _rcumsum(m)  # composite mass of links >= i
    mn = _next(mc)
    hx = _rcumsum(k.hx + mn * rx)  # composite first moment about p_i
    hz = _rcumsum(k.hz + mn * rz)
    J = _rcumsum(k.J + 2 * (rx * _next(hx) + rz * _next(hz)) + mn * (rx * rx + rz * rz))
    S = k.S
    # F_i = Ic_i S_i at p_i
    Ft = s.add(s.add(s.mul(J, S[0]), s.mul(-hz, S[1])), s.mul(hx, S[2]))
    Fx = s.add(s.mul(-hz, S[0]), s.mul(mc, S[1]))
    Fz = s.add(s.mul(hx, S[0]), s.mul(mc, S[2]))
    Ft, Fx, Fz = (jnp.broadcast_to(x, q.shape) for x in (Ft, Fx, Fz))
    px, pz = _cumsum(k.rx), _cumsum(k.rz)
    # M_ij (j <= i) = S_j . (F_i moved from p_i to p_j): moment Ft_i + cross(p_i - p_j, F_i)
    dx, dz = px[:, None] - px[None, :], pz[:, None] - pz[None, :]  # [i, j]
    Mt = Ft[:, None] + dx * Fz[:, None] - dz * Fx[:, None]
    Mij = s.add(s.add(s.mul(_col(S[0]), Mt), s.mul(_col(S[1]), Fx[:, None])), s.mul(_col(S[2]), Fz[:, None]))
    Mij = jnp.broadcast_to(Mij, dx.shape)
    lower = np.tril(np.ones((chain.n, chain.n), bool)).reshape((chain.n, chain.n) + (1,) * len(batch))
    M = jnp.where(lower, Mij, jnp.swapaxes(Mij, 0, 1))
    if chain.armature is not None:
        eye = np.eye(chain.n).reshape(M.shape[:2] + (1,) * len(batch))
        M = M + eye * _param(chain.armature, len(batch))[:, None]
    return jnp.moveaxis(M, (0, 1), (-2, -1))


def _col(x):
    """A per-link (n, *batch) array as the j index of an [i, j] array; constants pass through."""
    return x if s.is_const(x) else x[None, :]


# ------------------------------------------------------------------ ABA


def forward_dynamics(chain: Chain, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
    """``qdd = M^-1 (B u - C qd - T - D qd)`` by the articulated-body algorithm, shape (..., n).

    With ``implicit_damping_dt = h`` it solves with ``M + h diag(damping)`` (``D_i += h b_i``). With
    ``pivots=True`` it returns ``(qdd, singular)``: ``singular`` (shape ``batch``) is true where a
    pivot ``D_i`` (the factorisation of ``M`` that ABA performs) is not positive or not finite.
    """
    u = None if (u is None or chain.m == 0) else u
    batch, dtype, q, qd = _prepare(chain, q, qd, u)
    nb = len(batch)
    k = _Kin(chain, q, qd, nb)
    tau = _actuation(chain, u, batch, dtype)
    if chain.damping is not None:
        tau = s.sub(0.0 if tau is None else tau, _damping(chain, qd))
    extra = None
    if chain.armature is not None:
        extra = _param(chain.armature, nb)
    if implicit_damping_dt is not None and chain.damping is not None:
        extra = s.add(0.0 if extra is None else extra, implicit_damping_dt * _param(chain.damping, nb))
    S = k.S
    xs = dict(hx=k.hx, hz=k.hz, pt=k.pA[0], px=k.pA[1], pz=k.pA[2], rx=k.rx, rz=k.rz, cx=k.cx, cz=k.cz, tau=tau,
              s0=S[0], s1=S[1], s2=S[2])
    params = dict(m=k.m, J=k.J, extra=extra)
    xs, consts = _split_links(xs, params, nb)
    zero = jnp.zeros(batch, dtype)
    # a revolute joint without armature: U = (a, b, c), D = a, and the articulated inertia it passes on has a zero
    # first row and column (Ia = IA - U U^T / a), so only (d, e, f) and the bias force need computing
    revolute = all(s.is_const(x) for x in S) and S == (1.0, 0.0, 0.0) and s.is_zero(consts.get("extra", 1.0))

    def inward(carry, x):
        # carry: the child's articulated inertia (a, b, c, d, e, f) and bias force (t, x, z) at p_i
        x = {**consts, **x}
        s0, s1, s2 = x["s0"], x["s1"], x["s2"]
        a, b, c = s.add(x["J"], carry[0]), s.sub(carry[1], x["hz"]), s.add(x["hx"], carry[2])
        d, e, f = s.add(x["m"], carry[3]), carry[4], s.add(x["m"], carry[5])
        pt, px, pz = s.add(x["pt"], carry[6]), s.add(x["px"], carry[7]), s.add(x["pz"], carry[8])
        U0 = s.add(s.add(s.mul(a, s0), s.mul(b, s1)), s.mul(c, s2))
        U1 = s.add(s.add(s.mul(b, s0), s.mul(d, s1)), s.mul(e, s2))
        U2 = s.add(s.add(s.mul(c, s0), s.mul(e, s1)), s.mul(f, s2))
        D = s.add(s.add(s.add(s.mul(s0, U0), s.mul(s1, U1)), s.mul(s2, U2)), x["extra"])
        inv = 1.0 / D
        uu = s.sub(x["tau"], s.add(s.add(s.mul(s0, pt), s.mul(s1, px)), s.mul(s2, pz)))
        W0, W1, W2 = U0 * inv, U1 * inv, U2 * inv
        if revolute:
            a = b = c = 0.0
            pt = x["tau"]  # pt + W0 uu with W0 = 1
        else:
            a, b, c = a - U0 * W0, b - U0 * W1, c - U0 * W2
        d, e, f = d - U1 * W1, s.sub(e, U1 * W2), f - U2 * W2
        # pa = pA + Ia c + U u / D (c has no angular part)
        cx, cz = x["cx"], x["cz"]
        if not revolute:
            pt = s.add(s.add(s.add(pt, s.mul(b, cx)), s.mul(c, cz)), W0 * uu)
        px = s.add(s.add(s.add(px, s.mul(d, cx)), s.mul(e, cz)), W1 * uu)
        pz = s.add(s.add(s.add(pz, s.mul(e, cx)), s.mul(f, cz)), W2 * uu)
        # to the parent's reference point: X(r)^T Ia X(r), X(r)^T pa with perp(r) = (-rz, rx)
        qx, qz = s.neg(x["rz"]), x["rx"]
        b2 = s.add(s.add(b, s.mul(qx, d)), s.mul(qz, e))
        c2 = s.add(s.add(c, s.mul(qx, e)), s.mul(qz, f))
        a = s.add(s.add(a, s.mul(qx, s.add(b, b2))), s.mul(qz, s.add(c, c2)))
        pt = s.add(s.add(pt, s.mul(qx, px)), s.mul(qz, pz))
        out = dict(W1=W1, W2=W2, ui=uu * inv) | ({} if revolute else dict(W0=W0))  # revolute: W0 = U0 / D = 1
        if pivots:
            out["inv"] = inv
        return _arrays((a, b2, c2, d, e, f, pt, px, pz), zero), _arrays(out, zero)

    _, ys = _scan(inward, (zero,) * 9, xs, reverse=True)
    g = 0.0 if chain.gravity is None else chain.gravity
    ys |= {key: xs[key] for key in ("rx", "rz", "cx", "cz", "s0", "s1", "s2") if key in xs}

    def outward(acc, y):
        y = {**consts, "W0": 1.0, **y}
        al, ax, az = acc
        ax = s.add(s.sub(ax, s.mul(al, y["rz"])), y["cx"])
        az = s.add(s.add(az, s.mul(al, y["rx"])), y["cz"])
        qdd = s.sub(y["ui"], s.add(s.add(s.mul(y["W0"], al), s.mul(y["W1"], ax)), s.mul(y["W2"], az)))
        al = s.add(al, s.mul(y["s0"], qdd))
        ax, az = s.add(ax, s.mul(y["s1"], qdd)), s.add(az, s.mul(y["s2"], qdd))
        return _arrays((al, ax, az), zero), qdd

    _, qdd = _scan(outward, (zero, zero, zero + g), ys)
    if not pivots:
        return _out(qdd)
    inv = ys["inv"]  # 1 / D_i, (n, *batch)
    return _out(qdd), jnp.any(~((inv > 0) & jnp.isfinite(inv)), axis=0)


def _split_links(xs, params, nb):
    """The scan inputs of per-link arrays ``xs`` (each (n, *batch), a constant or None) and parameters ``params``
    (each (n, 1, ..., 1) as :func:`_param` shapes them, a constant or None): the arrays to slice link by link (the
    parameters as (n,)), and the constants (``None`` read as 0) that stay out of the loop."""
    arrays, consts = {}, {}
    for key, v in (xs | params).items():
        if v is None or s.is_const(v):
            consts[key] = 0.0 if v is None else v
        else:
            arrays[key] = jnp.reshape(v, v.shape[:1]) if key in params else v
    return arrays, consts


def _scan(body, init, xs, reverse=False):
    """``lax.scan`` over the links, the body rematerialised in reverse mode so that its residuals
    are the carries only (measured at n = 20, batch 1024: gradient compile 1.9 s instead of 15 s,
    and 25% faster). Not unrolled: with the per-link tuple bodies, ``unroll=2`` and ``4`` were slower at
    n = 8 and 32 at batch 1 and 1024 alike (forward 1.5-10x, gradient 1.5-10x) and compiled 2-4x longer."""
    return jax.lax.scan(jax.checkpoint(body), init, xs, reverse=reverse)


# ------------------------------------------------------------------ energy


def energy(chain: Chain, q, qd):
    """``(kinetic, potential)`` energy [J], potential zero at the chain's origin."""
    batch, _, q, qd = _prepare(chain, q, qd)
    k = _Kin(chain, q, qd, len(batch))
    # kinetic energy of body i = 1/2 v^T I v with the momentum from the spatial inertia
    t, Fx, Fz = k.momentum(k.w, k.vx, k.vz)
    kin = 0.5 * jnp.sum(k.w * t + k.vx * Fx + k.vz * Fz, axis=0)
    if chain.armature is not None:
        kin = kin + 0.5 * jnp.sum(_param(chain.armature, len(batch)) * qd * qd, axis=0)
    if chain.gravity is None:
        pot = jnp.zeros_like(kin)
    else:
        pz = _cumsum(k.rz)  # height of p_i; the centre of mass is h / m above it
        pot = chain.gravity * jnp.sum(jnp.broadcast_to(k.m * pz + k.hz, q.shape), axis=0)
    return kin, pot
