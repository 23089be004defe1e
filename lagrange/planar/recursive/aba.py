"""The articulated-body algorithm: forward dynamics in O(n).

Inward, ``IA_i = I_i + sum_c X_c^T Ia_c X_c``, ``pA_i = v_i x* I_i v_i + sum_c X_c^T pa_c`` (``c`` the children of
``i``), ``U_i = IA_i S_i``,
``D_i = S_i . U_i + armature_i``, ``u_i = tau_i - S_i . pA_i``, ``Ia_i = IA_i - U_i U_i^T / D_i``,
``pa_i = pA_i + Ia_i c_i + U_i u_i / D_i``; outward, ``a'_i = X_i a_{i-1} + c_i``, ``qdd_i = (u_i - U_i . a'_i) / D_i``,
``a_i = a'_i + S_i qdd_i``. The two passes are scans over the links, each step's inputs and outputs separate arrays of
the batch's shape; on a tree they run segment by segment, a branch point summing its child segments' articulated
inertias and bias forces (:class:`~lagrange.planar.recursive.tree.Topology`). Armature and an implicit-damping term
``h damping_i`` add to ``D_i``, which is adding them to ``M_ii``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.math import scalar as s
from lagrange.forces import clamp_controls
from lagrange.planar.model import PlanarChain
from lagrange.planar.recursive.contact import contact_wrenches
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.recursive.rnea import passive_force
from lagrange.planar.recursive.tree import arrays, links_last, param, prepare, split_links


def actuation(chain: PlanarChain, u, batch, dtype):
    """The actuation's generalized forces ``B u``, links first.

    Args:
        chain: the :class:`~lagrange.planar.model.PlanarChain`.
        u: controls, shape ``(*batch, m)``, or ``None``.
        batch: the batch shape.
        dtype: the float type.

    Returns:
        ``B u`` of shape ``(n, *batch)`` [N m or N], ``u`` clamped into its ranges first; ``None`` without control.
    """
    if u is None or chain.m == 0:
        return None
    u = clamp_controls(chain, jnp.asarray(u))
    u = jnp.moveaxis(jnp.broadcast_to(u, batch + u.shape[-1:]), -1, 0)
    gu = param(chain.gear, len(batch)).astype(dtype) * u
    if chain.actuated == tuple(range(chain.n)):
        return gu
    select = np.zeros((chain.n, chain.m))  # B / gear: a 0/1 matrix (a dot, not a scatter)
    select[list(chain.actuated), range(chain.m)] = 1.0
    return jnp.tensordot(jnp.asarray(select, dtype), gu, axes=1)


def forward_dynamics(chain: PlanarChain, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False):
    """Joint accelerations ``qdd = M^-1 (B u - bias)`` by the articulated-body algorithm, in O(n).

    Arguments and result as :func:`lagrange.dynamics.forward_dynamics`'s, for a chain that function has prepared
    (its concrete parameters folded to NumPy arrays); nothing is checked here. ``pivots=True`` also returns
    ``singular`` (shape ``batch``), true where a pivot ``D_i`` of the factorisation of ``M`` that ABA performs is
    not positive or not finite (:func:`lagrange.dynamics.forward_dynamics_and_pivots`).
    """
    u = None if (u is None or chain.m == 0) else u
    batch, dtype, q, qd = prepare(chain, q, qd, u)
    nb = len(batch)
    k = LinkKinematics(chain, q, qd, nb)
    tau = actuation(chain, u, batch, dtype)
    passive = passive_force(chain, q, qd)
    if passive is not None:
        tau = s.sub(0.0 if tau is None else tau, passive)
    extra = None
    if chain.armature is not None:
        extra = param(chain.armature, nb)
    if implicit_damping_dt is not None and chain.damping is not None:
        extra = s.add(0.0 if extra is None else extra, implicit_damping_dt * param(chain.damping, nb))
    S = k.S
    pA = k.pA
    external = contact_wrenches(chain, k)
    if external is not None:  # the contact forces leave the links' bias forces
        pA = tuple(a - f for a, f in zip(pA, external))
    xs = dict(hx=k.hx, hz=k.hz, pt=pA[0], px=pA[1], pz=pA[2], rx=k.rx, rz=k.rz, cx=k.cx, cz=k.cz, tau=tau,
              s0=S[0], s1=S[1], s2=S[2])
    params = dict(m=k.m, J=k.J, extra=extra)
    xs, consts = split_links(xs, params, nb)
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
        return arrays((a, b2, c2, d, e, f, pt, px, pz), zero), arrays(out, zero)

    _, ys = k.topology.scan_inward(inward, (zero,) * 9, xs)
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
        return arrays((al, ax, az), zero), qdd

    _, qdd = k.topology.scan_outward(outward, (zero, zero, zero + g), ys)
    if not pivots:
        return links_last(qdd)
    inv = ys["inv"]  # 1 / D_i, (n, *batch)
    return links_last(qdd), jnp.any(~((inv > 0) & jnp.isfinite(inv)), axis=0)
