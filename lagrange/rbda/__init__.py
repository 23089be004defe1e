"""The dynamics of a spatial tree (:class:`lagrange.model.tree.Tree`): Featherstone's algorithms written once against
the joints of :mod:`lagrange.model.joints`, vectorised over the links.

Every spatial vector is in world-aligned coordinates at the tree's reference point (:mod:`~.kinematics`), so the
recursions need no transform between links: RNEA (:mod:`~.rnea`) and CRBA (:mod:`~.crba`) are products with the
tree's 0/1 path matrix over all links at once, the frames a few rounds of pointer jumping, and the forward dynamics
solves ``M qdd = tau - bias`` by a Cholesky factorisation (as MuJoCo and MJX do): a step's program has a size set by
the joint kinds and ``log2`` of the depth, not by the number of links, and compiles in about a second for a humanoid.
Call the public functions of :mod:`lagrange.dynamics` (``mass_matrix``, ``bias_forces``, ``forward_dynamics``, ...),
which take a :class:`~lagrange.model.tree.Tree` as they take a chain; these are their
implementations. Shapes: ``q (*batch, nq)``, ``qd`` and ``qdd (*batch, nv)``, ``u (*batch, m)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from lagrange.math import spatial as al
from lagrange.model.joints import Ball, Free
from lagrange.rbda.crba import crba
from lagrange.rbda.contact import contact_energy, contact_wrenches
from lagrange.rbda.forces import actuation, limit_energy, limit_forces, passive, per_dof, spring_potential
from lagrange.rbda.kinematics import Kinematics
from lagrange.rbda.muscles import muscle_lengths, muscle_torques, muscle_wrenches
from lagrange.rbda.rnea import rnea
from lagrange.model.tree import WORLD, Tree

__all__ = ["actuated_forces", "bias_forces", "com_positions", "contact_point_positions", "dexpinv", "energy",
           "forward_dynamics", "gravity_forces", "integrate_positions", "inverse_dynamics", "mass_matrix",
           "muscle_lengths", "muscle_torques", "normalize_quaternions", "positions", "position_derivative",
           "tip_positions"]


def _broadcast(q, *xs):
    """``q`` and ``xs`` (``(..., k)`` arrays or ``None``) broadcast to their common batch shape and dtype."""
    arrays = [x for x in (q, *xs) if x is not None]
    batch = jnp.broadcast_shapes(*(x.shape[:-1] for x in arrays))
    dtype = jnp.result_type(*arrays)
    return tuple(None if x is None else jnp.broadcast_to(x, batch + x.shape[-1:]).astype(dtype) for x in (q, *xs))


def _minus(a, b):
    return a if b is None else a - b


def mass_matrix(tree: Tree, q):
    return crba(Kinematics(tree, _broadcast(q)[0]))


def _external(k: Kinematics, u=None):
    """The contact forces and, with the controls ``u``, the muscles' on the links; ``None`` without either."""
    tree = k.tree
    contact = None if tree.contact is None else contact_wrenches(k)
    if u is None or not tree.muscles:
        return contact
    return _total(contact, muscle_wrenches(k, u[..., len(tree.motors):]))


def _total(*terms):
    """The sum of the terms that are not ``None`` (``None`` when every one is)."""
    present = [t for t in terms if t is not None]
    return sum(present[1:], present[0]) if present else None


def bias_forces(tree: Tree, q, qd):
    """``qfrc_bias - qfrc_passive`` (velocity products, gravity, minus the dampers' and springs' forces), minus the
    limits' and the contact's generalized forces."""
    q, qd = _broadcast(q, qd)
    k = Kinematics(tree, q, qd)
    return _minus(rnea(k, external=_external(k)), _total(passive(tree, q, qd), limit_forces(tree, q, qd)))


def gravity_forces(tree: Tree, q):
    q = _broadcast(q)[0]
    return rnea(Kinematics(tree, q), velocity=False)


def inverse_dynamics(tree: Tree, q, qd, qdd):
    """``M qdd + bias``: the rigid bodies' forces (RNEA), the armature's ``armature qdd``, minus the passive ones."""
    q, qd, qdd = _broadcast(q, qd, qdd)
    tau = rnea(Kinematics(tree, q, qd), qdd)
    armature = per_dof(tree, "armature")
    if armature is not None:
        tau = tau + armature * qdd
    return _minus(tau, passive(tree, q, qd))


def _rhs(k: Kinematics, q, qd, u, external=None):
    """``tau - bias``: the actuators' (motors' and muscles') generalized forces, the dampers', springs', limits' and
    the contact's, less the rigid bodies' velocity products and gravity, at the kinematics ``k``."""
    tree = k.tree
    return _total(-rnea(k, external=_total(external, _external(k, u))), actuation(tree, u, q, qd),
                  passive(tree, q, qd), limit_forces(tree, q, qd))


def actuated_forces(tree: Tree, q, qd, u=None):
    """``tau(u) - bias``, the right-hand side of ``M qdd = tau - bias``, with one kinematics (what a step with a held
    mass matrix solves for)."""
    q, qd, u = _broadcast(q, qd, None if u is None or tree.m == 0 else u)
    return _rhs(Kinematics(tree, q, qd), q, qd, u)


def forward_dynamics(tree: Tree, q, qd, u=None, implicit_damping_dt=None, *, pivots: bool = False, external=None):
    """``qdd`` (and with ``pivots``, where the factorisation fails) under the motors' and the muscles' ``u``, the
    dampers and springs, the limits, the ground contact and ``external`` spatial forces on the links (``(..., n, 6)``)
    if given: ``M qdd = tau - bias`` solved by a Cholesky factorisation of ``M`` (``M + h diag(damping)`` with
    ``implicit_damping_dt = h``)."""
    q, qd, u = _broadcast(q, qd, None if u is None or tree.m == 0 else u)
    k = Kinematics(tree, q, qd)
    rhs = _rhs(k, q, qd, u, external)
    M = crba(k)
    damping = per_dof(tree, "damping")
    if implicit_damping_dt is not None and damping is not None:
        M = M + jnp.diag(implicit_damping_dt * jnp.asarray(damping, M.dtype))
    L = jnp.linalg.cholesky(M)
    qdd = jax.scipy.linalg.cho_solve((L, True), rhs[..., None])[..., 0]
    if not pivots:
        return qdd
    piv = jnp.diagonal(L, axis1=-2, axis2=-1) ** 2  # not finite where M is not positive definite
    return qdd, jnp.any(~((piv > 0) & jnp.isfinite(piv)), axis=-1)


def energy(tree: Tree, q, qd):
    """``(kinetic, potential)``: ``1/2 qd^T M qd`` (armature included) and the potential of gravity, the springs,
    the limits and the contact."""
    q, qd = _broadcast(q, qd)
    k = Kinematics(tree, q, qd)
    kin = 0.5 * jnp.sum(k.v * al.rigid_apply(k.m, k.h, k.J, k.v), axis=(-2, -1))
    armature = per_dof(tree, "armature")
    if armature is not None:
        kin = kin + 0.5 * jnp.sum(armature * qd * qd, axis=-1)
    g = jnp.asarray(tree.gravity, q.dtype)
    # gravity's potential: -m g . x_com over the links (their first moments about the reference points, plus m o)
    pot = -jnp.sum((k.h + k.m[:, None] * k.o) * g, axis=(-2, -1))
    return kin, _total(pot, spring_potential(tree, q), limit_energy(tree, q),
                       None if tree.contact is None else contact_energy(k))


def _body_frames(tree: Tree, q):
    """Every body's rotation and origin in the world, ``(..., bodies, 3, 3)`` and ``(..., bodies, 3)``: a body's frame
    is its link's (welded bodies: their link's, then their placements)."""
    q = _broadcast(q)[0]
    k = Kinematics(tree, q)
    st = k.structure
    R_links, p_links = k.R, k.o + k.p
    Rs, ps = [], []
    for b, body in enumerate(tree.bodies):
        link = st.body_link[b]
        if link == WORLD or st.link_body[link] != b:
            if tree.parents[b] == WORLD:
                R = al.quat_to_matrix(jnp.broadcast_to(jnp.asarray(body.quat, q.dtype), q.shape[:-1] + (4,)))
                p = jnp.broadcast_to(jnp.asarray(body.pos, q.dtype), q.shape[:-1] + (3,))
            else:
                Rp, pp = Rs[tree.parents[b]], ps[tree.parents[b]]
                R = al.matmul(Rp, al.quat_to_matrix(jnp.asarray(body.quat, q.dtype)))
                p = pp + al.matvec(Rp, jnp.asarray(body.pos, q.dtype))
        else:
            R, p = R_links[..., link, :, :], p_links[..., link, :]
        Rs.append(R)
        ps.append(p)
    return jnp.stack(Rs, axis=-3), jnp.stack(ps, axis=-2)


def positions(tree: Tree, q):
    """Every body's origin in the world [m], shape ``(*batch, bodies, 3)``."""
    return _body_frames(tree, q)[1]


def com_positions(tree: Tree, q):
    """Every body's centre of mass in the world [m], shape ``(*batch, bodies, 3)``."""
    R, p = _body_frames(tree, q)
    com = jnp.stack([jnp.asarray(b.com, p.dtype) for b in tree.bodies])
    return p + al.matvec(R, com)


def tip_positions(tree: Tree, q):
    """Every body's ``tip`` in the world [m] (its origin where it has none), shape ``(*batch, bodies, 3)``."""
    R, p = _body_frames(tree, q)
    tips = jnp.stack([jnp.zeros(3, p.dtype) if b.tip is None else jnp.asarray(b.tip, p.dtype) for b in tree.bodies])
    return p + al.matvec(R, tips)


def contact_point_positions(tree: Tree, q):
    """Every body's contact points (their centres, not lowered by the radius) in the world [m], bodies in order and
    each body's points in order, shape ``(*batch, k, 3)``."""
    R, p = _body_frames(tree, q)
    out = [p[..., b, :] + al.matvec(R[..., b, :, :], jnp.asarray(c[:3], p.dtype))
           for b, body in enumerate(tree.bodies) for c in body.contacts]
    return jnp.stack(out, axis=-2) if out else jnp.zeros(p.shape[:-2] + (0, 3), p.dtype)


def dexpinv(tree: Tree, theta, v):
    """The velocities ``v`` (``(..., nv)``) as the rate of the tangent increment ``theta`` (``(..., nv)``) from a base
    point: a ball's and a free joint's angular part ``w`` becomes ``J_r(theta)^-1 w = w + theta x w / 2 +
    c(|theta|) theta x (theta x w)``, ``c(t) = 1/t^2 - (1 + cos t) / (2 t sin t)`` (SO(3)'s inverse right Jacobian;
    ``q = q0 exp(theta)`` moves with body angular velocity ``w`` when ``d theta/dt`` is this); the rest unchanged.
    Runge-Kutta-Munthe-Kaas stages through it keep a Runge-Kutta method's order on the quaternions."""
    parts, start = [], 0
    for link, j in enumerate(tree.joints):
        if isinstance(j, (Ball, Free)):
            a = tree.vadr[link] + j.nv - 3
            th, w = theta[..., a: a + 3], v[..., a: a + 3]
            t2 = jnp.sum(th * th, axis=-1, keepdims=True)
            small = t2 < 1e-6
            t = jnp.sqrt(jnp.where(small, 1.0, t2))
            c = jnp.where(small, 1.0 / 12 + t2 / 720 + t2 * t2 / 30240,
                          1.0 / jnp.where(small, 1.0, t2) - (1 + jnp.cos(t)) / (2 * t * jnp.sin(t)))
            cw = al.cross(th, w)
            parts += [v[..., start: a], w + 0.5 * cw + c * al.cross(th, cw)]
            start = a + 3
    if not parts:
        return v
    return jnp.concatenate(parts + [v[..., start:]], axis=-1)


def normalize_quaternions(tree: Tree, q):
    """``q`` with every ball's and free joint's quaternion divided by its norm (``(..., nq)``)."""
    parts = []
    for link, j in enumerate(tree.joints):
        x = q[..., tree.qadr[link]: tree.qadr[link] + j.nq]
        if isinstance(j, (Ball, Free)):
            x = jnp.concatenate([x[..., :-4], al.normalize_quat(x[..., -4:])], axis=-1)
        parts.append(x)
    return jnp.concatenate(parts, axis=-1)


def integrate_positions(tree: Tree, q, v, h):
    """``q`` moved by the velocities ``v`` for ``h`` seconds on the joints' manifold (MuJoCo's ``mj_integratePos``):
    hinges and slides by ``h v``, quaternions by the exponential map, kept unit."""
    parts = []
    for link, j in enumerate(tree.joints):
        qa, va = tree.qadr[link], tree.vadr[link]
        parts.append(j.integrate(q[..., qa: qa + j.nq], v[..., va: va + j.nv], h))
    return jnp.concatenate(parts, axis=-1)


def position_derivative(tree: Tree, q, v):
    """``dq/dt`` at velocities ``v``: ``v`` for hinges and slides, ``1/2 q (0, w)`` for a quaternion (the
    derivative the adaptive solvers integrate in ``R^nq``; the quaternions are renormalised after each interval)."""
    parts = []
    for link, j in enumerate(tree.joints):
        qa, va = tree.qadr[link], tree.vadr[link]
        x, w = q[..., qa: qa + j.nq], v[..., va: va + j.nv]
        if isinstance(j, (Ball, Free)):
            lin = [] if isinstance(j, Ball) else [w[..., :3]]
            quat, omega = x[..., -4:], w[..., -3:]
            dq = al.quat_multiply(quat, jnp.concatenate([jnp.zeros_like(omega[..., :1]), omega], axis=-1))
            parts.extend(lin + [0.5 * dq])
        else:
            parts.append(w)
    return jnp.concatenate(parts, axis=-1)
