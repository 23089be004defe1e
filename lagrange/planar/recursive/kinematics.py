"""The kinematics of every link, as the recursive algorithms need them: one scan outward over the links.

:class:`LinkKinematics` holds, per link, the joint's motion subspace, the offset from the parent's reference point,
the link angle's sine and cosine, the spatial velocity and the velocity-product acceleration, the mass, first moment
and inertia about the joint, and the gyroscopic bias force ``v x* I v``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.math import scalar as s
from lagrange.math.scalar import cos_sin
from lagrange.math.sincos import sincos
from lagrange.planar.model import WORLD, PlanarChain
from lagrange.planar.recursive.tree import Topology, arrays, momentum, param, per_link


class LinkKinematics:
    """Per-link kinematics, every array shaped (n, *batch) (or a Python float when static).

    ``S``: the joint axes; ``r``: ``p_i - p_parent``; ``sin``/``cos``: of phi_i; ``w``, ``v``: the
    spatial velocity at ``p_i``; ``c``: ``v_i x S_i qd_i`` (linear part; its angular part is 0);
    ``m``, ``h``, ``J``: mass, first moment ``m com d(phi_i)`` and inertia about ``p_i``;
    ``pA``: ``v_i x* I_i v_i``. Velocity terms are ``None`` when ``qd`` is.

    Computed by one ``lax.scan`` outward over the links (on a tree too, each link's carry coming from its parent,
    :meth:`lagrange.planar.recursive.tree.Topology.scan_outward`): each step is a few dozen multiplies on
    arrays of the batch's shape, which XLA's CPU backend vectorises, where cumulative sums over the link axis
    (``reduce_window``) cost several times more. The link angles' sines and cosines come from the angle-addition
    formulas on the joint angles' (one :func:`sincos` of every joint before the scan): a polynomial sine inside the
    step cost two kernels per link (one per output, each evaluating both polynomials), 10% of the forward step at
    n = 32. Against the exact sines of the summed angles the errors are <= 1.3e-15 at n = 32 and 1.9e-15 at n = 64
    (``tests/lagrange/planar/test_recursive.py``).
    """

    def __init__(self, chain: PlanarChain, q, qd, nb: int, topology: Topology | None = None):
        dtype = q.dtype
        n = chain.n
        self.topology = Topology(chain) if topology is None else topology
        rev = np.array([j == "revolute" for j in chain.joints])
        off = np.asarray(chain.frame_offsets(), float)
        L = lambda x: per_link(x, dtype)  # noqa: E731
        if chain.serial:
            poff = np.concatenate([[0.0], off[:-1]])  # the parent frame's offset
            lp = chain.length  # the parent's length, 0 for the first link
            if isinstance(lp, np.ndarray):
                lp = np.concatenate([[0.0], lp[:-1]])
            else:
                lp = jnp.concatenate([jnp.zeros((1,), lp.dtype), lp[:-1]])
        else:
            poff, lp = _parent_offsets_and_lengths(chain, off)
        cs_p = np.array([cos_sin(o) for o in poff]).reshape(n, 2)
        # the joint angles' sines and cosines, every link at once (sense_i q_i; a prismatic joint's: 0 and 1)
        turn = rev * np.asarray(chain.senses, float)  # d phi_i / d q_i: the revolute joints' senses, 0 for a slide
        flipped = bool(np.any(turn < 0))
        sq, cq = sincos(q if rev.all() and not flipped else q * param(jnp.asarray(turn, dtype), nb))
        xs = dict(sq=sq, cq=cq) | ({} if rev.all() else dict(q=q))
        if chain.attach is None:
            params = dict(ld=lp * cs_p[:, 0], le=lp * cs_p[:, 1])
        else:  # an attach point (x, z) on the parent is -z d + x e in the parent's frame, turned by its offset
            cd, ce = _attach_coefficients(chain, lp)
            params = dict(ld=cd * cs_p[:, 0] - ce * cs_p[:, 1], le=cd * cs_p[:, 1] + ce * cs_p[:, 0])
        if not rev.all():
            axes = np.asarray(chain.axes) + poff
            params |= dict(rev=turn, pri=(~rev).astype(float), ca=np.cos(axes), sa=np.sin(axes))
        elif flipped:
            params |= dict(rev=turn)
        m, com = chain.mass, chain.com
        cs = np.array([cos_sin(o) for o in off]).reshape(n, 2)
        cn = 0.0 if chain.com_normal is None else chain.com_normal
        # the centre of mass c_d d(phi + off) + c_e e(phi + off), on d(phi) and e(phi)
        cd, ce = com * cs[:, 0] - cn * cs[:, 1], com * cs[:, 1] + cn * cs[:, 0]
        params |= dict(mcd=m * cd, mce=m * ce)
        J = chain.inertia + m * (com * com + cn * cn)
        self.m, self.J = (v if isinstance(v, float) else param(v, nb) for v in (L(m), L(J)))
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
                S = (x.get("rev", 1.0), 0.0, 0.0)
            hx = s.add(s.mul(x["mcd"], sin), s.mul(x["mce"], cos))
            hz = s.sub(s.mul(x["mce"], sin), s.mul(x["mcd"], cos))
            out = dict(sin=sin, cos=cos, rx=rx, rz=rz, hx=hx, hz=hz)
            if not all(isinstance(v, float) for v in S):
                out |= dict(s0=S[0], s1=S[1], s2=S[2])
            else:  # the same for every link
                constant_axis["S"] = S
            if qd is None:
                return (sin, cos), arrays(out, zero)
            w, vx, vz = carry[2:]
            qdi = x["qd"]
            sw, svx, svz = s.mul(S[0], qdi), s.mul(S[1], qdi), s.mul(S[2], qdi)
            vx = s.add(s.add(vx, s.mul(s.neg(w), rz)), svx)
            vz = s.add(s.add(vz, s.mul(w, rx)), svz)
            w = s.add(w, sw)
            # c = v x (S qd) = (0, w perp(sv) - sw perp(v))
            cx = s.add(s.neg(s.mul(w, svz)), s.mul(sw, vz))
            cz = s.sub(s.mul(w, svx), s.mul(sw, vx))
            t, Fx, Fz = momentum(x["J"], hx, hz, x["m"], w, vx, vz)
            out |= dict(w=w, vx=vx, vz=vz, cx=cx, cz=cz,
                        pt=s.sub(s.mul(vx, Fz), s.mul(vz, Fx)), px=s.neg(s.mul(w, Fz)), pz=s.mul(w, Fx))
            return (sin, cos) + arrays((w, vx, vz), zero), arrays(out, zero)

        constant_axis = {}
        init = (zero, zero + 1.0) + ((zero, zero, zero) if qd is not None else ())
        _, ys = self.topology.scan_outward(step, init, xs)
        self.sin, self.cos, self.rx, self.rz, self.hx, self.hz = (ys[k] for k in ("sin", "cos", "rx", "rz", "hx", "hz"))
        self.S = (ys["s0"], ys["s1"], ys["s2"]) if "s0" in ys else constant_axis["S"]
        self.w = self.vx = self.vz = self.cx = self.cz = self.pA = None
        if qd is not None:
            self.w, self.vx, self.vz, self.cx, self.cz = (ys[k] for k in ("w", "vx", "vz", "cx", "cz"))
            self.pA = (ys["pt"], ys["px"], ys["pz"])

    def momentum(self, w, vx, vz):
        """``I_i (w, vx, vz)``: the spatial inertia times a motion."""
        return momentum(self.J, self.hx, self.hz, self.m, w, vx, vz)


def _parent_offsets_and_lengths(chain: PlanarChain, off):
    """Each link's parent's frame offset and length (0 and 0 for a link of the world), on a tree."""
    parents = np.asarray(chain.parents)
    of_world = parents == WORLD
    poff = np.where(of_world, 0.0, off[np.maximum(parents, 0)])
    length = chain.length
    xp = np if isinstance(length, np.ndarray) else jnp
    return poff, xp.where(of_world, 0.0, length[np.maximum(parents, 0)])


def _attach_coefficients(chain: PlanarChain, lp):
    """``(c_d, c_e)`` per link: the joint at ``c_d d + c_e e`` of the parent's frame, ``(l_parent, 0)`` by default and
    ``(-z, x)`` for an ``attach`` point ``(x, z)``."""
    idx = np.asarray(chain.attached)
    x, z = chain.attach[:, 0], chain.attach[:, 1]
    if isinstance(lp, np.ndarray) and isinstance(chain.attach, np.ndarray):
        cd, ce = np.array(lp, dtype=float), np.zeros(chain.n)
        cd[idx], ce[idx] = -z, x
        return cd, ce
    cd = jnp.asarray(lp).at[idx].set(-z)
    return cd, jnp.zeros(chain.n, cd.dtype).at[idx].set(x)
