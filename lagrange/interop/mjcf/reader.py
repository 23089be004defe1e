"""Reading MJCF: the planar models people hold as MJCF, through MuJoCo's own compiler, as exact chains and trees.

:func:`from_mjcf` reads a model as a :class:`~lagrange.chain.Chain` whose ``q``, ``qd`` and ``u`` are MuJoCo's
``qpos``, ``qvel`` and ``ctrl`` (the docs' "Importing MJCF"), with its joint ranges and ground contact as penalty laws
or left out, and refuses by name what a planar tree cannot reproduce.
Reading needs MuJoCo (``pip install -e ".[mjcf]"``), imported when first called.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lagrange.chain import WORLD, Chain, Link
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits
from lagrange.interop.mjcf.refusals import (element_name, geom_points, ground_geoms, ground_plane, is_limited,
                                            refuse)
from lagrange.interop.mjcf.runtime import compile_model, import_mujoco
from lagrange.interop.mjcf.tree_reader import tree_from_model
from lagrange.model.tree import Tree

LIMITS = ("raise", "ignore")
"""What :func:`from_mjcf` does with a limited joint: refuse the model, or load it without the limit."""

CONTACTS = ("raise", "ignore")
"""What :func:`from_mjcf` does with geoms that can touch: refuse the model, or load it without contact."""

_TOL = 1e-9  # a geometric tolerance [m or rad]: parallel axes, in-plane directions, zero lengths


def _plane(mujoco, model, data):
    """The chain's plane as world unit vectors ``(x, y, z)``, right-handed, with the first hinge turning about ``-y``
    (so that ``q = qpos``; a hinge about ``+y`` is a joint of ``sense=-1``) and gravity's in-plane part along ``-z``;
    and that part's magnitude."""
    nm = lambda kind, i: element_name(mujoco, model, kind, i)  # noqa: E731
    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    slides = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE]
    g = np.zeros(3) if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY else np.array(model.opt.gravity)
    axes = {j: np.array(data.xaxis[j]) for j in range(model.njnt)}
    if hinges:
        n = axes[hinges[0]]
        for j in hinges[1:]:
            if np.linalg.norm(np.cross(axes[j], n)) > _TOL:
                raise NotImplementedError(
                    f"from_mjcf: {nm('joint', j)}'s axis {axes[j].round(6).tolist()} is not parallel to "
                    f"{nm('joint', hinges[0])}'s {n.round(6).tolist()}: the chain leaves the plane"
                )
    else:
        plane = [axes[j] for j in slides]
        cross = [np.cross(a, b) for a in plane for b in plane if np.linalg.norm(np.cross(a, b)) > _TOL]
        n = cross[0] if cross else np.cross(plane[0], g) if np.linalg.norm(np.cross(plane[0], g)) > _TOL else None
        if n is None:  # one slide direction, along gravity or without it: any plane through it
            n = np.cross(plane[0], [1.0, 0, 0] if abs(plane[0][0]) < 0.9 else [0, 1.0, 0])
        n = n / np.linalg.norm(n)
    for j in slides:
        if abs(axes[j] @ n) > _TOL:
            raise NotImplementedError(f"from_mjcf: {nm('joint', j)} slides along {axes[j].round(6).tolist()}, out of "
                                      f"the plane normal to {n.round(6).tolist()} in which the chain moves")
    y = -n
    g_in = g - (g @ n) * n
    G = float(np.linalg.norm(g_in))
    if G > 0:
        z = -g_in / G
    else:  # no gravity in the plane (a horizontal reacher): world z, else x, projected onto it
        for w in (np.array([0, 0, 1.0]), np.array([1.0, 0, 0])):
            z = w - (w @ n) * n
            if np.linalg.norm(z) > 1e-6:
                break
        z = z / np.linalg.norm(z)
    x = np.cross(y, z)
    return (x, y, z), G


def _planar(mujoco, model, data):
    """:func:`_plane`'s ``((x, y, z), g)`` when every joint is a hinge or a slide in one plane, else ``None``."""
    kinds = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    if any(mujoco.mjtJoint(t) not in kinds for t in model.jnt_type):
        return None
    try:
        return _plane(mujoco, model, data)
    except NotImplementedError:
        return None


def _d(theta):
    return np.array([math.sin(theta), -math.cos(theta)])


def _e(theta):
    return np.array([math.cos(theta), math.sin(theta)])


def _wrap(a: float) -> float:
    """``a`` in (-pi, pi]."""
    a = math.remainder(a, 2 * math.pi)
    return math.pi if a == -math.pi else a


def from_mjcf(source, *, limits: str | PenaltyLimits = "raise", contact: str | PenaltyContact = "raise",
              tree: bool | None = None) -> Chain | Tree:
    """A chain (a planar model) or a spatial tree (any other) read from MJCF or URDF, with ``q`` equal to ``qpos``.

    The model is compiled by MuJoCo itself (inertias from geoms, defaults classes, ``fromto``, degrees,
    includes), so this reads the compiled ``mujoco.MjModel`` at ``qpos = 0``. The contract: ``q`` is ``qpos``
    (same order, sign and zero), ``qd`` is ``qvel``, ``u`` is ``ctrl`` (actuator order, clamped into
    ``ctrlrange`` where the actuator is ``ctrllimited``); ``mass_matrix``, ``bias_forces`` and
    ``forward_dynamics`` then equal ``mj_fullM``, ``qfrc_bias - qfrc_passive`` and ``qacc``, and
    :func:`~lagrange.interop.mjcf.solver_of` names the integrator that reproduces ``mj_step``.

    A model whose joints are all hinges and slides moving in one plane is read as a planar
    :class:`~lagrange.chain.Chain` (below); any other (ball or free joints, hinges about several axes, a URDF arm)
    as a :class:`~lagrange.model.tree.Tree` (:func:`~lagrange.interop.mjcf.tree_reader.tree_from_model`: body for body,
    joint for joint); ``tree=True`` reads a planar model as a tree too. A URDF file is compiled by MuJoCo as it
    compiles any ``<robot>``: its root welded to the world.

    How a model maps onto a chain:

    - The plane is the one normal to the hinges' common axis (or spanned by the slides); its ``z`` is
      against gravity's in-plane part and :attr:`Chain.gravity` that part's magnitude (gravity along the
      normal does no work on a planar chain). Positions (:func:`lagrange.positions`) are in this plane,
      relative to the first joint's anchor at ``qpos = 0``.
    - One link per joint, in ``qpos`` order. A body with several joints (a planar floating base's ``rootx``,
      ``rootz``, ``rooty``) becomes massless links for all but its last joint; bodies without a joint are merged
      into the body they are welded to (mass, centre of mass, and the moment of inertia about the plane's normal,
      by the parallel-axis theorem). A link's parent is the link of the joint before it in its body, else the
      last joint of the jointed body it hangs from, else the world: branches (the cheetah's and the walker's legs)
      and second trees (the reacher's target) keep MuJoCo's structure.
    - A hinge turning about the opposite axis to the first hinge is a joint of ``sense=-1``
      (``phi = phi_parent - q``), so that still ``q = qpos``.
    - Each link's frame points from its joint's anchor to its first child's (frame offsets carry the
      angles between them at ``qpos = 0``, a hinge's ``ref`` included); its other children sit at ``attach``
      points, and a link of the world at its anchor. A slide's ``ref`` shifts where it sits at ``qpos = 0``.
      Joint ``damping``, ``armature``, ``stiffness`` and ``springref`` are the joint's own; each motor's
      ``gear * gain`` is the link's gear.

    Args:
        source: a path to an MJCF or URDF file, an MJCF string, or a compiled ``mujoco.MjModel``.
        limits: ``"raise"`` (refuse a model with a limited joint), ``"ignore"`` (load it without the
            limits: exact while every joint stays inside its range), or a :class:`lagrange.PenaltyLimits`: each
            limited joint gets its ``range`` and the chain this penalty law (not MuJoCo's constraint solver).
        contact: ``"raise"`` (refuse a model in which two geoms can touch), ``"ignore"`` (load it without
            contact: exact while nothing touches, e.g. a walker in the air), or a :class:`lagrange.PenaltyContact`:
            ground contact, DFlex's penalty law, not MuJoCo's soft-constraint solver. The ground is the model's one
            plane geom of the world body (its height replaces the law's ``ground``); the contact points come from
            the capsules (both end points) and spheres (the centre), each with its radius, and for a tree the boxes
            (their corners), that MuJoCo's ``contype``/``conaffinity`` rule lets touch that plane; any other geom type
            that can touch it is refused by name. Contacts between the model's own geoms are left out (DFlex has
            none).

        tree: ``None`` (a chain when the model is planar, else a tree), ``True`` (a tree) or ``False`` (a chain, or
            refuse).

    Returns:
        The :class:`~lagrange.chain.Chain` or :class:`~lagrange.model.tree.Tree` (float64 where JAX's x64 is enabled).

    Raises:
        ImportError: without MuJoCo (``pip install -e ".[mjcf]"``).
        ValueError: for a limited joint with ``limits="raise"``, a bad ``limits`` or ``contact``, a model
            without joints.
        NotImplementedError: naming the element, for what neither can reproduce (:func:`.refusals.refuse`):
            contacts that can occur (with ``contact="raise"``), friction loss, tendons that carry force, equality
            constraints, gravity compensation, fluid forces, actuators other than motors with a positive gear on a
            hinge or slide, force limits, two motors on one joint; for a tree, a limited ball joint with penalty
            limits and a limited tendon unless ``limits="ignore"``; with ``tree=False``, what
            only a tree can hold (ball or free joints, hinges not parallel, slides out of the plane).
    """
    if not isinstance(limits, PenaltyLimits) and limits not in LIMITS:
        raise ValueError(f"from_mjcf: limits must be one of {LIMITS} or a lagrange.PenaltyLimits, got {limits!r}")
    if not isinstance(contact, PenaltyContact) and contact not in CONTACTS:
        raise ValueError(f"from_mjcf: contact must be one of {CONTACTS} or a lagrange.PenaltyContact, got {contact!r}")
    if tree not in (None, True, False):
        raise ValueError(f"from_mjcf: tree must be None (a chain when the model is planar), True or False, got "
                         f"{tree!r}")
    mujoco = import_mujoco()
    model = compile_model(source)
    if model.nq == 0:
        raise ValueError("from_mjcf: the model has no joint; a chain or tree needs at least one")
    data = mujoco.MjData(model)
    data.qpos[:] = 0.0
    mujoco.mj_kinematics(model, data)
    servo = any(model.actuator_biastype[a] != mujoco.mjtBias.mjBIAS_NONE or model.actuator_forcelimited[a]
                for a in range(model.nu))  # only a tree carries them: a planar model with them is read as one
    plane = None if tree or (servo and tree is None) else _planar(mujoco, model, data)
    if plane is None and tree is not False:
        refuse(mujoco, model, limits, contact, planar=False)
        return tree_from_model(mujoco, model, limits, contact)
    refuse(mujoco, model, limits, contact, planar=True)
    (X, Y, Z), G = _plane(mujoco, model, data) if plane is None else plane
    origin = np.array(data.xanchor[0])
    to2 = lambda v: np.array([v @ X, v @ Z])  # noqa: E731  world vector -> plane (x, z)

    # the tree: each joint's body; a joint's parent is the joint before it in its body, else the last joint of the
    # jointed body its body hangs from (MuJoCo lists bodies, and so joints, parents first)
    weld, parent_body = model.body_weldid, model.body_parentid
    n = model.njnt
    body = [int(model.jnt_bodyid[j]) for j in range(n)]
    last_joint = {b: max(j for j in range(n) if body[j] == b) for b in set(body)}
    parents = []
    for j in range(n):
        if j > 0 and body[j] == body[j - 1]:
            parents.append(j - 1)
        else:
            hangs_from = int(weld[parent_body[body[j]]])
            parents.append(WORLD if hangs_from == 0 else last_joint[hangs_from])
    children = {j: [c for c in range(n) if parents[c] == j] for j in range(n)}

    # each jointed body's rigid group (itself and the bodies welded to it): mass, centre of mass, planar moment
    groups = {}
    for b in sorted(set(body)):
        members = [k for k in range(model.nbody) if weld[k] == b]
        m = float(sum(model.body_mass[k] for k in members))
        c = sum(model.body_mass[k] * np.array(data.xipos[k]) for k in members) / m if m > 0 else np.array(data.xpos[b])
        inertia = 0.0
        for k in members:
            R = np.array(data.ximat[k]).reshape(3, 3)
            inertia += float(np.sum(model.body_inertia[k] * (R.T @ Y) ** 2))
            r = to2(np.array(data.xipos[k]) - c)
            inertia += float(model.body_mass[k] * (r @ r))
        groups[b] = (m, to2(c - origin), inertia)

    anchor = [to2(np.array(data.xanchor[j]) - origin) for j in range(n)]
    last_of_body = [j == n - 1 or body[j + 1] != body[j] for j in range(n)]
    actuator = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)}
    clamp = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
    damper = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_DAMPER
    spring = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SPRING
    touching, ground = {}, None
    if isinstance(contact, PenaltyContact):
        touching, ground = _ground_contacts(mujoco, model, data, last_joint, origin, Z, to2)
        contact = eqx.tree_at(lambda c: c.ground, contact, jnp.asarray(ground, contact.ground.dtype))
    links, theta = [], []
    for j in range(n):
        p = parents[j]
        theta_parent = 0.0 if p == WORLD else theta[p]
        m, c, inertia = groups[body[j]] if last_of_body[j] else (0.0, anchor[j], 0.0)
        first = children[j][0] if children[j] else None
        tip = anchor[first] - anchor[j] if first is not None else np.zeros(2)
        length = float(np.hypot(*tip))
        arm = c - anchor[j]
        if length > _TOL:
            t = math.atan2(tip[0], -tip[1])
        elif m > 0 and np.hypot(*arm) > _TOL:
            t, length = math.atan2(arm[0], -arm[1]), 0.0
        else:
            t, length = theta_parent, 0.0
        theta.append(t)
        kw = {}
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            sd = to2(np.array(data.xaxis[j]))
            kw["axis"] = _wrap(math.atan2(sd[1], sd[0]) - theta_parent)
        d = int(model.jnt_dofadr[j])
        if j in actuator:
            a = actuator[j]
            kw["gear"] = float(model.actuator_gear[a, 0] * model.actuator_gainprm[a, 0])
            if clamp and model.actuator_ctrllimited[a]:
                kw["control_range"] = tuple(float(x) for x in model.actuator_ctrlrange[a])
        if spring and model.jnt_stiffness[j] != 0:
            kw["stiffness"] = float(model.jnt_stiffness[j])
            kw["springref"] = float(model.qpos_spring[model.jnt_qposadr[j]])
        # where the joint sits on its parent: the parent's tip unless it is not the parent's first child
        at = anchor[j] if p == WORLD else anchor[j] - anchor[p]
        if p == WORLD:
            kw["attach"] = None if np.hypot(*at) <= _TOL else (float(at[0]), float(at[1]))
        elif children[p][0] != j:  # (x, z) in the parent's frame: x along e, z against d
            kw["attach"] = (float(at @ _e(theta_parent)), float(-(at @ _d(theta_parent))))
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and np.array(data.xaxis[j]) @ Y > 0:
            kw["sense"] = -1  # turns about +y where the first hinge turns about -y
        if isinstance(limits, PenaltyLimits) and is_limited(mujoco, model, j):
            kw["range"] = tuple(float(x) for x in model.jnt_range[j])
        if j in touching:
            kw["contacts"] = [_in_frame(point - anchor[j], t) + (r,) for point, r in touching[j]]
        links.append(
            Link(
                "revolute" if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE else "prismatic",
                m,
                length,
                com=float(arm @ _d(t)),
                inertia=inertia,
                damping=float(model.dof_damping[d]) if damper else 0.0,
                armature=float(model.dof_armature[d]),
                com_normal=float(arm @ _e(t)),
                offset=_wrap(t - theta_parent),
                parent=p,
                **kw,
            )
        )
    return Chain(links, gravity=G, contact=contact if touching else None,
                 limits=limits if any(lk.range is not None for lk in links) else None)


def _in_frame(r, theta: float) -> tuple[float, float]:
    """Plane vector ``r`` as ``(x, z)`` in a frame of angle ``theta``: x along ``e(theta)``, z against ``d(theta)``."""
    return float(r @ _e(theta)), float(-(r @ _d(theta)))


def _ground_contacts(mujoco, model, data, last_joint, origin, Z, to2):
    """The contact points of the geoms that can touch the ground plane, per link (the last joint of each geom's
    rigid group): ``{link: [(point in the plane at qpos = 0, radius), ...]}``; and the plane's height."""
    nm = lambda kind, i: element_name(mujoco, model, kind, i)  # noqa: E731
    plane = ground_plane(mujoco, model)
    normal = np.array(data.geom_xmat[plane]).reshape(3, 3)[:, 2]
    if abs(normal @ Z) < 1 - 1e-9:
        raise NotImplementedError(f"from_mjcf: the ground {nm('geom', plane)} is not level in the chain's plane (its "
                                  f"normal {normal.round(6).tolist()} is not the plane's up {Z.round(6).tolist()})")
    height = float((np.array(data.geom_xpos[plane]) - origin) @ Z)
    weld = model.body_weldid
    touching: dict[int, list] = {}
    for g in ground_geoms(mujoco, model, plane):
        centre, R = np.array(data.geom_xpos[g]), np.array(data.geom_xmat[g]).reshape(3, 3)
        touching.setdefault(last_joint[int(weld[model.geom_bodyid[g]])], []).extend(
            (to2(e - origin), float(r)) for e, r in geom_points(mujoco, model, g, centre, R, boxes=False))
    return touching, height
