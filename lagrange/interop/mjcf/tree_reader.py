"""Reading a 3-D MJCF model (or URDF, through MuJoCo's compiler) as a spatial :class:`~lagrange.tree.Tree`.

The compiled ``mujoco.MjModel`` maps one to one: a body per body (its ``pos``, ``quat``, mass, centre of mass and
inertia turned by ``iquat``), its joints in order with their axes, anchors, ``ref`` (``qpos0``), damping, armature and
springs, and a :class:`~lagrange.tree.Motor` per motor (``gear * gain``, ``ctrlrange`` where ``ctrllimited``), so that
``q``, ``qd`` and ``u`` are ``qpos``, ``qvel`` and ``ctrl``.
"""

from __future__ import annotations

import numpy as np

from lagrange._spatial import quat_to_matrix
from lagrange.joints import Ball, Free, Hinge, Slide
from lagrange.tree import Body, Motor, Tree

__all__ = ["tree_from_model"]


def _clean(x):
    """Entries within 1e-15 of 0 as exact zeros (so that they fold), as a float array."""
    x = np.array(x, dtype=float)
    x[np.abs(x) < 1e-15] = 0.0
    return x


def _joint(mujoco, model, j):
    kind = mujoco.mjtJoint(model.jnt_type[j])
    d, a = int(model.jnt_dofadr[j]), int(model.jnt_qposadr[j])
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    damping = float(model.dof_damping[d]) if not off & bit.mjDSBL_DAMPER else 0.0
    stiffness = float(model.jnt_stiffness[j]) if not off & bit.mjDSBL_SPRING else 0.0
    common = dict(damping=damping, armature=float(model.dof_armature[d]), stiffness=stiffness)
    if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
        cls = Hinge if kind == mujoco.mjtJoint.mjJNT_HINGE else Slide
        return cls(_clean(model.jnt_axis[j]), _clean(model.jnt_pos[j]), ref=float(model.qpos0[a]),
                   springref=float(model.qpos_spring[a]), **common)
    if kind == mujoco.mjtJoint.mjJNT_BALL:
        return Ball(_clean(model.jnt_pos[j]), springref=np.array(model.qpos_spring[a: a + 4]), **common)
    return Free(springref=np.array(model.qpos_spring[a: a + 7]), **common)


def tree_from_model(mujoco, model) -> Tree:
    """The :class:`~lagrange.tree.Tree` of a compiled ``mujoco.MjModel`` (its refusals already made by the
    caller: :func:`lagrange.interop.mjcf.from_mjcf`)."""
    bodies = []
    for b in range(1, model.nbody):
        R = quat_to_matrix(np.asarray(model.body_iquat[b], float), np)
        inertia = _clean(R @ np.diag(model.body_inertia[b]) @ R.T)
        joints = [_joint(mujoco, model, j) for j in range(model.njnt) if model.jnt_bodyid[j] == b]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or None
        bodies.append(Body(float(model.body_mass[b]), inertia, _clean(model.body_ipos[b]), joints=joints,
                           parent=int(model.body_parentid[b]) - 1, pos=_clean(model.body_pos[b]),
                           quat=_clean(model.body_quat[b]), name=name))
    off = model.opt.disableflags
    gravity = np.zeros(3) if off & mujoco.mjtDisableBit.mjDSBL_GRAVITY else _clean(model.opt.gravity)
    clamp = not off & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
    motors = []
    for a in range(model.nu):
        control_range = (tuple(float(x) for x in model.actuator_ctrlrange[a])
                         if clamp and model.actuator_ctrllimited[a] else None)
        motors.append(Motor(int(model.actuator_trnid[a, 0]), float(model.actuator_gear[a, 0]
                                                                  * model.actuator_gainprm[a, 0]), control_range))
    return Tree(bodies, gravity, motors=motors)
