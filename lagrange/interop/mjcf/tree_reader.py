"""Reading a 3-D MJCF model (or URDF, through MuJoCo's compiler) as a spatial :class:`~lagrange.model.tree.Tree`.

The compiled ``mujoco.MjModel`` maps one to one: a body per body (its ``pos``, ``quat``, mass, centre of mass and
inertia turned by ``iquat``), its joints in order with their axes, anchors, ``ref`` (``qpos0``), damping, armature and
springs, a :class:`~lagrange.model.tree.Motor` per motor (``gear * gain``, ``ctrlrange`` where ``ctrllimited``) and an
:class:`~lagrange.model.tree.AffineActuator` per ``<position>``, ``<velocity>``, affine ``<general>`` or force-limited
actuator (``gainprm[0]``, ``biasprm[:3]``, ``forcerange`` where ``forcelimited``), so that ``q``, ``qd`` and ``u`` are
``qpos``, ``qvel`` and ``ctrl``.
"""

from __future__ import annotations

import numpy as np

from lagrange.math.spatial import quat_to_matrix
from lagrange.model.contact import PenaltyContact
from lagrange.interop.mjcf.refusals import element_name, geom_points, ground_geoms, ground_plane, is_limited
from lagrange.model.joints import Ball, Free, Hinge, Slide
from lagrange.model.limits import PenaltyLimits
from lagrange.model.tree import AffineActuator, Body, Motor, Tree

__all__ = ["tree_from_model"]


def _clean(x):
    """Entries within 1e-15 of 0 as exact zeros (so that they fold), as a float array."""
    x = np.array(x, dtype=float)
    x[np.abs(x) < 1e-15] = 0.0
    return x


def _joint(mujoco, model, j, limits):
    kind = mujoco.mjtJoint(model.jnt_type[j])
    limited = isinstance(limits, PenaltyLimits) and is_limited(mujoco, model, j)
    if limited and kind == mujoco.mjtJoint.mjJNT_BALL:
        raise NotImplementedError(f"from_mjcf: {element_name(mujoco, model, 'joint', j)} is a limited ball joint; "
                                  "PenaltyLimits presses hinges and slides only: limits=\"ignore\" loads it without "
                                  "the limit (exact while it is not reached)")
    d, a = int(model.jnt_dofadr[j]), int(model.jnt_qposadr[j])
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    damping = float(model.dof_damping[d]) if not off & bit.mjDSBL_DAMPER else 0.0
    stiffness = float(model.jnt_stiffness[j]) if not off & bit.mjDSBL_SPRING else 0.0
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or None
    common = dict(damping=damping, armature=float(model.dof_armature[d]), stiffness=stiffness, name=name)
    if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
        cls = Hinge if kind == mujoco.mjtJoint.mjJNT_HINGE else Slide
        return cls(_clean(model.jnt_axis[j]), _clean(model.jnt_pos[j]), ref=float(model.qpos0[a]),
                   springref=float(model.qpos_spring[a]),
                   range=tuple(float(x) for x in model.jnt_range[j]) if limited else None, **common)
    if kind == mujoco.mjtJoint.mjJNT_BALL:
        return Ball(_clean(model.jnt_pos[j]), springref=np.array(model.qpos_spring[a: a + 4]), **common)
    return Free(springref=np.array(model.qpos_spring[a: a + 7]), **common)


def _contacts(mujoco, model):
    """``({body: [(x, y, z, radius), ...]}, height)``: the contact points, in their bodies' frames, of the geoms that
    MuJoCo's ``contype``/``conaffinity`` rule lets touch the ground (the world's one plane geom, level), and the
    ground's height: both end points of a capsule, a sphere's centre, a box's eight corners (radius 0)."""
    plane = ground_plane(mujoco, model)
    normal = quat_to_matrix(np.asarray(model.geom_quat[plane], float), np)[:, 2]
    if normal[2] < 1 - 1e-9:
        raise NotImplementedError(f"from_mjcf: the ground {element_name(mujoco, model, 'geom', plane)} is not level "
                                  f"(its normal {normal.round(6).tolist()} is not +z)")
    points: dict[int, list] = {}
    for g in ground_geoms(mujoco, model, plane):
        centre, R = np.asarray(model.geom_pos[g], float), quat_to_matrix(np.asarray(model.geom_quat[g], float), np)
        points.setdefault(int(model.geom_bodyid[g]), []).extend(
            (*_clean(c).tolist(), float(r)) for c, r in geom_points(mujoco, model, g, centre, R))
    return points, float(model.geom_pos[plane][2])


def tree_from_model(mujoco, model, limits="ignore", contact="ignore") -> Tree:
    """The :class:`~lagrange.model.tree.Tree` of a compiled ``mujoco.MjModel`` (its refusals already made by the
    caller: :func:`lagrange.interop.mjcf.from_mjcf`), with ``PenaltyLimits`` on its limited hinges and slides and
    ``PenaltyContact`` on the geoms that can touch its ground where those are given."""
    points, height = _contacts(mujoco, model) if isinstance(contact, PenaltyContact) else ({}, 0.0)
    bodies = []
    for b in range(1, model.nbody):
        R = quat_to_matrix(np.asarray(model.body_iquat[b], float), np)
        inertia = _clean(R @ np.diag(model.body_inertia[b]) @ R.T)
        joints = [_joint(mujoco, model, j, limits) for j in range(model.njnt) if model.jnt_bodyid[j] == b]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or None
        bodies.append(Body(float(model.body_mass[b]), inertia, _clean(model.body_ipos[b]), joints=joints,
                           parent=int(model.body_parentid[b]) - 1, pos=_clean(model.body_pos[b]),
                           quat=_clean(model.body_quat[b]), contacts=points.get(b, ()), name=name))
    off = model.opt.disableflags
    gravity = np.zeros(3) if off & mujoco.mjtDisableBit.mjDSBL_GRAVITY else _clean(model.opt.gravity)
    clamp = not off & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
    motors = []
    for a in range(model.nu):
        control_range = (tuple(float(x) for x in model.actuator_ctrlrange[a])
                         if clamp and model.actuator_ctrllimited[a] else None)
        joint, gear = int(model.actuator_trnid[a, 0]), float(model.actuator_gear[a, 0])
        gain, limited = float(model.actuator_gainprm[a, 0]), bool(model.actuator_forcelimited[a])
        affine = model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        if affine or limited:
            bias = _clean(model.actuator_biasprm[a, :3]) if affine else np.zeros(3)
            force_range = tuple(float(x) for x in model.actuator_forcerange[a]) if limited else None
            motors.append(AffineActuator(joint, gear, control_range, gain=gain, bias=bias, force_range=force_range))
        else:
            motors.append(Motor(joint, gear * gain, control_range))
    law = None
    if points:
        law = PenaltyContact(contact.ke, contact.kd, contact.kf, contact.mu, height)
    limited = any(j.range is not None for body in bodies for j in body.joints)
    return Tree(bodies, gravity, motors=motors, contact=law, limits=limits if limited else None)
