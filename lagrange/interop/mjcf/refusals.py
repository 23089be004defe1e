"""What :func:`lagrange.interop.mjcf.from_mjcf` refuses, by name: the features of a compiled MuJoCo model that a tree
cannot reproduce exactly, and the contact pairs MuJoCo's collision driver would test."""

from __future__ import annotations

import numpy as np

__all__ = ["contact_pairs", "element_name", "is_limited", "refuse", "refuse_contacts"]


def element_name(mujoco, model, kind, i) -> str:
    """``kind 'name'`` of MuJoCo's element ``i`` of ``kind`` (``"joint"``, ``"body"``, ...), or ``kind #i``."""
    name = mujoco.mj_id2name(model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), i)
    return f"{kind} {name!r}" if name else f"{kind} #{i}"


def refuse(mujoco, model, limits, contact) -> None:
    """Raise for whatever a tree cannot reproduce exactly, naming the feature, the element and the way out: friction
    loss, force-carrying tendons, equality constraints, gravity compensation, fluid forces, actuators other than
    motors and affine actuators with a positive gear on a hinge or slide, a joint's actuatorfrcrange, two actuators on
    one joint, limited joints and tendons with ``limits="raise"``, touching geoms with ``contact="raise"``."""
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    constraints = not off & bit.mjDSBL_CONSTRAINT
    nm = lambda kind, i: element_name(mujoco, model, kind, i)  # noqa: E731
    if model.nq == 0:
        raise ValueError("from_mjcf: the model has no joint; a tree needs at least one")
    for j in range(model.njnt):
        if is_limited(mujoco, model, j) and isinstance(limits, str) and limits == "raise":
            raise ValueError(
                f"from_mjcf: {nm('joint', j)} is limited (range {model.jnt_range[j].tolist()}). from_mjcf(..., "
                "limits=lagrange.PenaltyLimits(ke, kd)) loads it with penalty limits, limits=\"ignore\" without them "
                "(exact while the joint stays inside its range)"
            )
    for d in range(model.nv):
        if model.dof_frictionloss[d] != 0 and constraints and not off & bit.mjDSBL_FRICTIONLOSS:
            raise NotImplementedError(
                f"from_mjcf: {nm('joint', model.dof_jntid[d])} has frictionloss {model.dof_frictionloss[d]} (dry "
                "friction, a constraint); set frictionloss=\"0\" or disable it (<flag frictionloss=\"disable\"/>)"
            )
    for t in range(model.ntendon):  # a tendon carries force by a spring, a damper, friction or a (kept) limit
        force = model.tendon_stiffness[t] != 0 or model.tendon_damping[t] != 0 or (
            model.tendon_frictionloss[t] != 0 and constraints and not off & bit.mjDSBL_FRICTIONLOSS)
        if force:
            raise NotImplementedError(f"from_mjcf: {nm('tendon', t)} carries force (stiffness, damping or friction); "
                                      "a tree has no tendons: remove it")
        if model.tendon_limited[t] and constraints and not off & bit.mjDSBL_LIMIT and not (
                isinstance(limits, str) and limits == "ignore"):
            raise NotImplementedError(f"from_mjcf: {nm('tendon', t)} is limited (range "
                                      f"{model.tendon_range[t].tolist()}); a tree has no tendon limits: "
                                      "limits=\"ignore\" loads it without the limit (exact while it is not reached)")
    if model.neq and constraints and not off & bit.mjDSBL_EQUALITY:
        raise NotImplementedError(f"from_mjcf: the model has {model.neq} equality constraint(s) ({nm('equality', 0)}); "
                                  "a tree has none: remove them or disable equality "
                                  "(<flag equality=\"disable\"/>)")
    if np.any(model.body_gravcomp != 0):
        b = int(np.flatnonzero(model.body_gravcomp)[0])
        raise NotImplementedError(f"from_mjcf: {nm('body', b)} has gravcomp {model.body_gravcomp[b]}; remove it")
    if model.opt.density != 0 or model.opt.viscosity != 0 or np.any(model.opt.wind != 0):
        raise NotImplementedError("from_mjcf: the model has fluid forces (option density, viscosity or wind non-zero); "
                                  "set them to 0")
    if off & bit.mjDSBL_ACTUATION and model.nu:
        raise NotImplementedError("from_mjcf: actuation is disabled (<flag actuation=\"disable\"/>) but the model has "
                                  "actuators; remove them or enable actuation")
    driven = {int(model.actuator_trnid[a, 0]) for a in range(model.nu)
              if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT}
    for j in np.flatnonzero(model.jnt_actfrclimited):  # without an actuator on the joint it clamps nothing
        if int(j) in driven:
            raise NotImplementedError(f"from_mjcf: {nm('joint', int(j))} has an actuatorfrcrange; a tree clamps each "
                                      "actuator's force (forcerange), not a joint's sum: give the actuator a "
                                      "forcerange")
    for a in range(model.nu):
        on_joint = (model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                    and model.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
                    and model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED)
        motor = on_joint and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
        affine = on_joint and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        if not (motor or affine):
            raise NotImplementedError(
                f"from_mjcf: {nm('actuator', a)} is neither a motor nor an affine actuator on a joint (a fixed gain, "
                "a bias affine in the joint's position and velocity, no activation dynamics): a tree takes <motor>, "
                "<position>, <velocity> and <general gaintype=\"fixed\" biastype=\"affine\"> on hinges and slides; "
                "tendon, site and body transmissions and activation dynamics (<intvelocity>, filters, muscles) are "
                "not modelled"
            )
        if affine or model.actuator_forcelimited[a]:
            if model.actuator_gear[a, 0] <= 0:
                raise NotImplementedError(f"from_mjcf: {nm('actuator', a)} has gear {model.actuator_gear[a, 0]}; an "
                                          "actuator's gear is > 0: flip the joint's axis and the actuator's gains")
        elif model.actuator_gear[a, 0] * model.actuator_gainprm[a, 0] <= 0:
            raise NotImplementedError(
                f"from_mjcf: {nm('actuator', a)} has gear * gain = "
                f"{model.actuator_gear[a, 0] * model.actuator_gainprm[a, 0]}"
                "; a motor's gear is > 0: flip the joint's axis or the gear's sign in the model"
            )
        j = int(model.actuator_trnid[a, 0])
        if mujoco.mjtJoint(model.jnt_type[j]) not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise NotImplementedError(f"from_mjcf: {nm('actuator', a)} drives {nm('joint', j)}, a ball or free joint; "
                                      "a motor drives a hinge or a slide: model the joint's motors on hinges")
    joints = model.actuator_trnid[: model.nu, 0]
    if len(set(joints.tolist())) < len(joints):
        j = int(next(x for x in joints if list(joints).count(x) > 1))
        raise NotImplementedError(f"from_mjcf: {nm('joint', j)} has more than one actuator; a tree's joint has one "
                                  "actuator: merge them")
    if isinstance(contact, str) and contact == "raise":
        refuse_contacts(mujoco, model, nm)


def is_limited(mujoco, model, j) -> bool:
    """Whether MuJoCo enforces joint ``j``'s range (limited, and neither constraints nor limits disabled)."""
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    return bool(model.jnt_limited[j]) and not off & bit.mjDSBL_CONSTRAINT and not off & bit.mjDSBL_LIMIT


def refuse_contacts(mujoco, model, nm) -> None:
    """Refuse a model in which a contact can occur: one explicit ``<pair>``, or two geoms whose contype/conaffinity
    bits match and that MuJoCo's body filters do not exclude (the same rules as its collision driver); the message
    names every pair that can touch (the first few) and the ways out."""
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    if off & bit.mjDSBL_CONSTRAINT or off & bit.mjDSBL_CONTACT:
        return
    way_out = ("from_mjcf(..., contact=lagrange.PenaltyContact(ke, kd, kf, mu)) loads it with penalty ground contact, "
               "contact=\"ignore\" without contact (exact while nothing touches); or disable "
               "contacts in the model (<option><flag contact=\"disable\"/></option>) or set contype=\"0\" "
               "conaffinity=\"0\" on the geoms")
    if model.npair:
        raise NotImplementedError(f"from_mjcf: the model has {model.npair} explicit contact pair(s) with "
                                  f"contact=\"raise\"; {way_out}")
    pairs = contact_pairs(mujoco, model)
    if pairs:
        shown = ", ".join(f"{nm('geom', g1)} and {nm('geom', g2)}" for g1, g2 in pairs[:4])
        more = f" and {len(pairs) - 4} more pair(s)" if len(pairs) > 4 else ""
        raise NotImplementedError(f"from_mjcf: geoms can touch ({shown}{more}) with contact=\"raise\"; "
                                  f"{way_out}")


def ground_plane(mujoco, model) -> int:
    """The ground that ``PenaltyContact`` presses a model against: the world body's one plane geom (its index), else
    an error naming how many there are."""
    planes = [g for g in range(model.ngeom)
              if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE and model.geom_bodyid[g] == 0]
    if len(planes) != 1:
        raise NotImplementedError(f"from_mjcf: contact=PenaltyContact(...) presses the model against its ground, the "
                                  f"one plane geom of the world body; the model has {len(planes)}")
    return planes[0]


def ground_geoms(mujoco, model, plane: int) -> list[int]:
    """The geoms that MuJoCo's ``contype``/``conaffinity`` rule lets touch the ground ``plane``, in order, leaving
    out those of the world body and of bodies welded to it (they cannot move)."""
    touching = {g for pair in contact_pairs(mujoco, model) if plane in pair for g in pair if g != plane}
    return [g for g in sorted(touching) if model.body_weldid[model.geom_bodyid[g]] != 0]


def geom_points(mujoco, model, g: int, centre, R) -> list[tuple[np.ndarray, float]]:
    """Geom ``g``'s contact points ``[(point, radius), ...]`` from its centre and rotation in any one frame: a
    capsule's two end points and a sphere's centre with their radius, a box's eight corners (radius 0);
    any other type is refused, naming the geom and the shapes taken."""
    kinds, size = mujoco.mjtGeom, np.asarray(model.geom_size[g], float)
    if model.geom_type[g] == kinds.mjGEOM_CAPSULE:
        return [(centre - R[:, 2] * size[1], size[0]), (centre + R[:, 2] * size[1], size[0])]
    if model.geom_type[g] == kinds.mjGEOM_SPHERE:
        return [(centre, size[0])]
    if model.geom_type[g] == kinds.mjGEOM_BOX:
        signs = [(sx, sy, sz) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
        return [(centre + R @ (np.array(sign) * size), 0.0) for sign in signs]
    raise NotImplementedError(
        f"from_mjcf: {element_name(mujoco, model, 'geom', g)} is a {kinds(model.geom_type[g]).name[7:].lower()} that "
        f"can touch the ground; PenaltyContact takes capsules, spheres and boxes: replace it, or set its contype and "
        "conaffinity to 0")


def contact_pairs(mujoco, model) -> list[tuple[int, int]]:
    """Every pair of geoms that MuJoCo's collision driver would test.

    Its rules: contype/conaffinity bits that match, not on one rigid body, not parent and child (unless
    ``filterparent`` is disabled), not excluded by an ``<exclude>``.

    Args:
        mujoco: the ``mujoco`` module.
        model: the compiled ``mujoco.MjModel``.

    Returns:
        The pairs ``(g1, g2)`` of geom indices, ``g1 < g2``, in order.
    """
    off = model.opt.disableflags
    bit = mujoco.mjtDisableBit
    excluded = {(int(model.exclude_signature[k] >> 16), int(model.exclude_signature[k] & 0xFFFF))
                for k in range(model.nexclude)}
    weld = model.body_weldid
    parent_weld = weld[model.body_parentid]
    filter_parent = not off & bit.mjDSBL_FILTERPARENT
    out = []
    for g1 in range(model.ngeom):
        for g2 in range(g1 + 1, model.ngeom):
            if not (model.geom_contype[g1] & model.geom_conaffinity[g2]
                    or model.geom_contype[g2] & model.geom_conaffinity[g1]):
                continue
            b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
            w1, w2 = weld[b1], weld[b2]
            if w1 == w2:
                continue
            if filter_parent and w1 != 0 and w2 != 0 and (w1 == parent_weld[b2] or w2 == parent_weld[b1]):
                continue
            if (min(b1, b2), max(b1, b2)) in excluded or (max(b1, b2), min(b1, b2)) in excluded:
                continue
            out.append((g1, g2))
    return out
