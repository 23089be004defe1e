"""Reading MJCF (and URDF, through MuJoCo's compiler) as a :class:`~lagrange.model.tree.Tree`, whatever the model:
planar or 3-D, the plane detected by the tree itself (:attr:`lagrange.Tree.planar`).

:func:`from_mjcf` reads a model whose ``q``, ``qd`` and ``u`` are MuJoCo's ``qpos``, ``qvel`` and ``ctrl`` (the docs'
"Importing MJCF"), with its joint ranges and ground contact as penalty laws or left out, and refuses by name what a
tree cannot reproduce. Reading needs MuJoCo (``pip install -e ".[mjcf]"``), imported when first called.
"""

from __future__ import annotations

import warnings

import numpy as np

from lagrange.interop.mjcf.refusals import element_name, refuse
from lagrange.interop.mjcf.runtime import compile_model, import_mujoco
from lagrange.interop.mjcf.tree_reader import tree_from_model
from lagrange.model.contact import PenaltyContact
from lagrange.model.limits import PenaltyLimits
from lagrange.model.plane import TOLERANCE
from lagrange.model.tree import Tree
from lagrange.planar.lower import lower

LIMITS = ("raise", "ignore")
"""What :func:`from_mjcf` does with a limited joint: refuse the model, or load it without the limit."""

CONTACTS = ("raise", "ignore")
"""What :func:`from_mjcf` does with geoms that can touch: refuse the model, or load it without contact."""


def from_mjcf(source, *, limits: str | PenaltyLimits = "raise", contact: str | PenaltyContact = "raise",
              tree: bool | None = None) -> Tree:
    """A :class:`~lagrange.model.tree.Tree` read from MJCF or URDF, with ``q`` equal to ``qpos``.

    The model is compiled by MuJoCo itself (inertias from geoms, defaults classes, ``fromto``, degrees,
    includes), and the compiled ``mujoco.MjModel`` maps one to one
    (:func:`~lagrange.interop.mjcf.tree_reader.tree_from_model`): a body per body, its joints in order with their
    axes, anchors, ``ref`` (so :meth:`lagrange.Tree.neutral` is ``qpos0``), damping, armature and springs, a motor
    or an affine actuator per actuator. The contract: ``q`` is ``qpos`` (same order, sign and zero), ``qd`` is
    ``qvel``, ``u`` is ``ctrl`` (actuator order, clamped into ``ctrlrange`` where the actuator is ``ctrllimited``);
    ``mass_matrix``, ``bias_forces`` and ``forward_dynamics`` then equal ``mj_fullM``, ``qfrc_bias - qfrc_passive``
    and ``qacc``, and :func:`~lagrange.interop.mjcf.solver_of` names the integrator that reproduces ``mj_step``.
    Positions, energies and the ground's height are in MuJoCo's world frame. A URDF file is compiled by MuJoCo as it
    compiles any ``<robot>``: its root welded to the world.

    A model whose joints are all hinges about one axis and slides across it (dm_control's, Gymnasium's and Brax's
    pendulums, cartpoles, reachers, hoppers, cheetahs and walkers) is a planar tree (:attr:`lagrange.Tree.planar`):
    its dynamics are the planar backend's (:mod:`lagrange.planar`) wherever its actuators are motors listed in
    joint order, and the general algorithms' otherwise; nothing about the reading differs.

    Args:
        source: a path to an MJCF or URDF file, an MJCF string, or a compiled ``mujoco.MjModel``.
        limits: ``"raise"`` (refuse a model with a limited joint), ``"ignore"`` (load it without the
            limits: exact while every joint stays inside its range), or a :class:`lagrange.PenaltyLimits`: each
            limited hinge and slide gets its ``range`` and the tree this penalty law (not MuJoCo's constraint
            solver).
        contact: ``"raise"`` (refuse a model in which two geoms can touch), ``"ignore"`` (load it without
            contact: exact while nothing touches, e.g. a walker in the air), or a :class:`lagrange.PenaltyContact`:
            ground contact, DFlex's penalty law, not MuJoCo's soft-constraint solver. The ground is the model's one
            plane geom of the world body, level (its height replaces the law's ``ground``); the contact points come
            from the capsules (both end points), spheres (the centre) and boxes (the corners), each with its radius,
            that MuJoCo's ``contype``/``conaffinity`` rule lets touch that plane; any other geom type that can touch
            it is refused by name. Contacts between the model's own geoms are left out (DFlex has none).
        tree: deprecated: every model is read as a tree. ``False`` refuses, naming the element, a model that the
            planar backend cannot carry (what ``tree=False`` asked for when it meant "a chain, or refuse").

    Returns:
        The :class:`~lagrange.model.tree.Tree` (float64 where JAX's x64 is enabled).

    Raises:
        ImportError: without MuJoCo (``pip install -e ".[mjcf]"``).
        ValueError: for a limited joint with ``limits="raise"``, a bad ``limits`` or ``contact``, a model
            without joints.
        NotImplementedError: naming the element, for what a tree cannot reproduce (:func:`.refusals.refuse`):
            contacts that can occur (with ``contact="raise"``), friction loss, tendons that carry force, equality
            constraints, gravity compensation, fluid forces, actuators other than motors and affine actuators with a
            positive gear on a hinge or slide, two actuators on one joint, a limited ball joint with penalty limits
            and a limited tendon unless ``limits="ignore"``; with ``tree=False``, what the planar backend cannot
            carry (ball or free joints, hinges not parallel, slides out of the plane, actuators other than motors).
    """
    if not isinstance(limits, PenaltyLimits) and limits not in LIMITS:
        raise ValueError(f"from_mjcf: limits must be one of {LIMITS} or a lagrange.PenaltyLimits, got {limits!r}")
    if not isinstance(contact, PenaltyContact) and contact not in CONTACTS:
        raise ValueError(f"from_mjcf: contact must be one of {CONTACTS} or a lagrange.PenaltyContact, got {contact!r}")
    if tree not in (None, True, False):
        raise ValueError(f"from_mjcf: tree must be None, True or False, got {tree!r}")
    if tree is not None:
        warnings.warn("from_mjcf's tree= is deprecated: every model is read as a lagrange.Tree, and Tree.planar tells "
                      "whether the planar backend runs it; drop the argument", DeprecationWarning, stacklevel=2)
    mujoco = import_mujoco()
    model = compile_model(source)
    refuse(mujoco, model, limits, contact)
    out = tree_from_model(mujoco, model, limits, contact)
    if tree is False and lower(out) is None:
        raise NotImplementedError(f"from_mjcf(..., tree=False): {_off_plane(mujoco, model, out)}; the planar backend "
                                  "cannot carry it: read it without tree=False (a tree on the general algorithms)")
    return out


def _off_plane(mujoco, model, tree: Tree) -> str:
    """Why the planar backend cannot carry ``tree`` (read from ``model``), naming the element: where the tree is not
    planar, a joint that is neither hinge nor slide, a hinge not parallel to the first, a slide out of their plane;
    else an actuator other than a motor, actuators out of joint order, or a ground that is not a line of the plane."""
    nm = lambda kind, i: element_name(mujoco, model, kind, i)  # noqa: E731
    if not tree.planar:
        kinds = mujoco.mjtJoint
        for j in range(model.njnt):
            if kinds(model.jnt_type[j]) not in (kinds.mjJNT_HINGE, kinds.mjJNT_SLIDE):
                return f"{nm('joint', j)} is a {kinds(model.jnt_type[j]).name[6:].lower()} joint"
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        axes = np.array(data.xaxis)
        hinges = [j for j in range(model.njnt) if model.jnt_type[j] == kinds.mjJNT_HINGE]
        for j in hinges[1:]:
            if np.linalg.norm(np.cross(axes[j], axes[hinges[0]])) > TOLERANCE:
                return (f"{nm('joint', j)}'s axis {axes[j].round(6).tolist()} is not parallel to "
                        f"{nm('joint', hinges[0])}'s {axes[hinges[0]].round(6).tolist()}: the model leaves the plane")
        for j in range(model.njnt):
            if hinges and model.jnt_type[j] == kinds.mjJNT_SLIDE and abs(axes[j] @ axes[hinges[0]]) > TOLERANCE:
                return f"{nm('joint', j)} slides along {axes[j].round(6).tolist()}, out of the plane of the hinges"
        return "its slides move along three independent directions, out of any one plane"
    for a in range(model.nu):
        if model.actuator_forcelimited[a]:
            return f"{nm('actuator', a)} is force-limited (the planar backend carries motors only)"
        if model.actuator_biastype[a] != mujoco.mjtBias.mjBIAS_NONE:
            return f"{nm('actuator', a)} is not a motor: its bias makes it a servo (the planar backend carries motors)"
    joints = [mo.joint for mo in tree.motors]
    if joints != sorted(joints):
        return (f"its actuators drive joints {joints}, out of joint order (the planar backend's k-th control drives "
                "its k-th actuated joint)")
    return "its ground is not a level line of its plane"
