"""The generalized forces beside the rigid-body dynamics of a spatial tree: the joints' dampers and springs (MuJoCo's
``qfrc_passive``) and the motors (``qfrc_actuator``), as arrays ``(..., nv)``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.forces import clamp_controls, motor_matrix
from lagrange.model.joints import Free
from lagrange.model.tree import Tree

__all__ = ["actuation", "limit_energy", "limit_forces", "passive", "per_dof", "spring_potential"]


def _zero(x) -> bool:
    return not isinstance(x, jax.core.Tracer) and float(np.asarray(x)) == 0.0


def per_dof(tree: Tree, field: str):
    """A joint parameter (``"damping"``, ``"armature"``) repeated over each joint's velocities: ``(nv,)``, in NumPy
    when concrete; ``None`` when it is exactly zero on every joint."""
    values = [getattr(j, field) for j in tree.joints]
    if all(_zero(v) for v in values):
        return None
    reps = [j.nv for j in tree.joints]
    if any(isinstance(v, jax.core.Tracer) for v in values):
        return jnp.concatenate([jnp.full((r,), v) for v, r in zip(values, reps)])
    return np.repeat(np.array([float(np.asarray(v)) for v in values]), reps)


def passive(tree: Tree, q, qd):
    """``-damping qd - stiffness (q - springref)`` per dof (a ball's and a free joint's rotation: the rotation vector
    from the rest quaternion), ``(..., nv)``, the springs only where ``q`` is given, the dampers where ``qd`` is;
    ``None`` when the tree has neither."""
    out = None
    damping = per_dof(tree, "damping")
    if qd is not None and damping is not None:
        out = -jnp.asarray(damping, qd.dtype) * qd
    if q is not None:
        for link, j, qj, ref in _springs(tree, q):
            d = j.spring(qj, ref)
            force = jnp.zeros(q.shape[:-1] + (tree.nv,), q.dtype)
            force = force.at[..., tree.vadr[link]: tree.vadr[link] + j.nv].set(-jnp.asarray(j.stiffness, d.dtype) * d)
            out = force if out is None else out + force
    return out


def _springs(tree: Tree, q):
    """``(link, joint, its coordinates (..., nq_j), its spring's rest coordinates)`` of every joint with a spring (not
    exactly zero stiffness)."""
    for link, j in enumerate(tree.joints):
        if _zero(j.stiffness):
            continue
        ref = j.springref
        if isinstance(j, Free) and ref is None:
            b = tree.bodies[tree.joint_body[link]]
            ref = jnp.concatenate([jnp.asarray(b.pos), jnp.asarray(b.quat)])
        yield link, j, q[..., tree.qadr[link]: tree.qadr[link] + j.nq], ref


def spring_potential(tree: Tree, q):
    """The springs' potential ``1/2 stiffness |displacement|^2`` (a joint's own, :meth:`spring_energy`), ``(...)``;
    ``None`` without springs."""
    terms = [0.5 * j.stiffness * j.spring_energy(qj, ref) for _, j, qj, ref in _springs(tree, q)]
    return sum(terms[1:], terms[0]) if terms else None


def actuation(tree: Tree, u, q=None, qd=None):
    """The motors' generalized forces (MuJoCo's ``qfrc_actuator``), ``(..., nv)``: ``B u`` with ``u`` clamped into
    the motors' ranges first, and for an actuator whose force depends on its joint's state
    (:class:`lagrange.model.tree.AffineActuator`) ``gear * force(u, gear q_j, gear qd_j)``; ``None`` without motors or
    control. The muscles' activations (the controls after the motors') are not read here: their forces need the
    kinematics (:mod:`lagrange.rbda.muscles`)."""
    if u is None or not tree.motors:
        return None
    if tree.muscles:
        u = u[..., :len(tree.motors)]
    u = clamp_controls(tree, u)
    if not any(mo.state_dependent for mo in tree.motors):
        return jnp.einsum("ij,...j->...i", motor_matrix(tree).astype(u.dtype), u)
    forces = []
    for k, mo in enumerate(tree.motors):
        qa, va = tree.qadr[mo.joint], tree.vadr[mo.joint]
        gear = jnp.asarray(mo.gear, u.dtype)
        forces.append(gear * mo.force(u[..., k], gear * q[..., qa], gear * qd[..., va]))
    E = np.zeros((tree.nv, len(tree.motors)))
    E[list(tree.actuated), np.arange(len(tree.motors))] = 1.0
    return jnp.einsum("ik,...k->...i", jnp.asarray(E, u.dtype), jnp.stack(jnp.broadcast_arrays(*forces), -1))


def _limited(tree: Tree):
    """``(coordinate indices, velocity indices, lower, upper)`` of the hinges and slides with a ``range``."""
    idx = [k for k, j in enumerate(tree.joints) if j.range is not None]
    lo = np.array([tree.joints[k].range[0] for k in idx])
    hi = np.array([tree.joints[k].range[1] for k in idx])
    return np.array([tree.qadr[k] for k in idx], int), np.array([tree.vadr[k] for k in idx], int), lo, hi


def limit_forces(tree: Tree, q, qd):
    """The limits' generalized forces ``(..., nv)`` (:class:`lagrange.PenaltyLimits`); ``None`` without limits."""
    if tree.limits is None:
        return None
    qa, va, lo, hi = _limited(tree)
    tau = tree.limits.forces(q[..., qa], qd[..., va], jnp.asarray(lo, q.dtype), jnp.asarray(hi, q.dtype))
    E = (np.arange(tree.nv)[:, None] == va[None, :]).astype(float)
    return jnp.einsum("...k,ik->...i", tau, jnp.asarray(E, q.dtype))


def limit_energy(tree: Tree, q):
    """The limit springs' potential energy ``(...)``; ``None`` without limits."""
    if tree.limits is None:
        return None
    qa, _, lo, hi = _limited(tree)
    return jnp.sum(tree.limits.energy(q[..., qa], jnp.asarray(lo, q.dtype), jnp.asarray(hi, q.dtype)), axis=-1)
