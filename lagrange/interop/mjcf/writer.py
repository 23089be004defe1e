"""Writing MJCF: any tree as a model string that MuJoCo, MJX and Brax simulate exactly, and that
:func:`~lagrange.interop.mjcf.from_mjcf` reads back.

:func:`to_mjcf` returns the model as an XML string; MuJoCo, MJX and Brax load it with their own readers::

    import mujoco

    from lagrange import systems
    from lagrange.interop.mjcf import to_mjcf

    model = mujoco.MjModel.from_xml_string(to_mjcf(systems.acrobot(), timestep=0.01))

Writing needs neither MuJoCo nor Brax. The tree is written body for body:

- One ``<body>`` per body, nested in its parent's, at its ``pos`` and ``quat``; its joints in order (``hinge`` and
  ``slide`` with their axis, anchor, ``ref``, damping, armature and spring; ``ball``; ``free``), named ``q{k}`` in the
  tree's joint order; a ``<motor>`` per motor with its gear and ``ctrlrange`` (limited only where the motor has a
  ``control_range``) and no force limits; the tree's gravity. A :class:`~lagrange.chain.Chain`'s bodies are its links
  (:mod:`lagrange.chain` says how): body ``i`` named ``link{i}``, its hinge about ``(0, -sense, 0)``.
- Each body carries an explicit ``<inertial>`` (``inertiafromgeom="false"``): the centre of mass, the mass and the
  inertia (``diaginertia`` where it is diagonal, as a chain's ``diag(I, I, I)``, else ``fullinertia``). MuJoCo rejects
  a moving body whose mass or principal inertia is below ``1e-15``: such a value is written as ``tiny`` (default
  ``1e-12``), the only way the written model can differ from the tree (by at most ``tiny`` times a squared lever arm).
- Geoms are for looking only (``contype="0" conaffinity="0"``, no mass: the inertials are explicit): a capsule from
  each body's origin to its ``tip``, a sphere at the origin where the tip is there or the body has none (so that every
  body shows in a viewer, and Brax, which needs a geom, loads any tree).
- ``<custom><numeric name="matrix_inv_iterations" data="0"/></custom>`` makes Brax's generalized pipeline solve with
  the exact mass matrix (its default approximates the inverse by Newton-Schulz iterations), so Brax, MuJoCo and
  :class:`lagrange.SemiImplicitEuler` agree step for step.
- The penalty laws of contact and joint limits have no MJCF form (MuJoCo's are constraints): a tree with one is
  refused by name.
"""

from __future__ import annotations

import math

import jax
import numpy as np

from lagrange.model.joints import Ball, DFlexBall, Free, Hinge, Slide
from lagrange.model.tree import WORLD, AffineActuator, Tree, check_tree
from lagrange.model.muscles import Muscle

INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
"""The MuJoCo integrators :func:`to_mjcf` accepts (Brax loads only ``"Euler"``)."""

__all__ = ["INTEGRATORS", "to_mjcf"]


def _num(x) -> str:
    """A float written so that MuJoCo reads back exactly the same double."""
    x = float(x)
    return "0" if x == 0.0 else repr(x)


def _vec(xs) -> str:
    return " ".join(_num(x) for x in np.asarray(xs, float).reshape(-1))


def _concrete(x, what: str):
    if isinstance(x, jax.core.Tracer):
        raise TypeError(f"to_mjcf needs concrete parameters; {what} is traced (call it outside jit/grad)")
    return np.asarray(x, dtype=float)


def to_mjcf(
    tree: Tree,
    timestep: float = 0.01,
    integrator: str = "Euler",
    name: str = "chain",
    *,
    radius: float = 0.02,
    tiny: float = 1e-12,
) -> str:
    """The tree as an MJCF model string, for ``mujoco.MjModel.from_xml_string`` or ``brax.io.mjcf.loads`` (the module
    docstring says how it is written).

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`~lagrange.chain.Chain` is one), concrete parameters (not traced).
        timestep: MuJoCo's ``option/timestep`` [s], finite and > 0.
        integrator: one of ``"Euler"`` (MuJoCo's semi-implicit Euler, the one Brax loads and
            :class:`lagrange.SemiImplicitEuler` reproduces), ``"RK4"``, ``"implicit"``, ``"implicitfast"``.
        name: the model's name (letters, digits, ``_-.``).
        radius: radius [m] of the visual capsules, > 0; it has no effect on the dynamics.
        tiny: the value written for a zero mass or principal moment of inertia of a moving body, which MuJoCo
            rejects; must be in ``(1e-15, 1e-6]``.

    Returns:
        The MJCF XML as a string. Joint ``k`` is named ``q{k}``, actuator ``k`` ``u{k}`` (the motors', then the
        muscles' order), so MuJoCo's ``qpos``, ``qvel`` and ``ctrl`` line up with ``q``, ``qd`` and ``u``. A muscle
        (:class:`lagrange.Muscle`, DFlex's law) is a spatial tendon ``m{k}`` through sites ``m{k}_{i}`` at its
        waypoints, driven by a ``<general>`` actuator on it of gain ``-strength`` and ``ctrlrange="0 1"``
        (MuJoCo's tendon force pulls along ``+dL``, so the negative gain contracts): ``ten_length`` is ``L`` and
        ``qfrc_actuator`` the muscle's ``-F dL/dq``.

    Raises:
        TypeError: for a model that is not a tree, traced parameters, a timestep that is not a number.
        ValueError: for a bad timestep, integrator, name, radius or tiny.
        NotImplementedError: for a tree with a contact or limit law, a ball's or free joint's spring whose rest
            pose is not the body as written, or a muscle whose law is not DFlex's (a subclass of
            :class:`lagrange.Muscle` that overrides ``tension``).
    """
    check_tree(tree, "tree")
    if isinstance(timestep, bool) or not isinstance(timestep, (int, float, np.floating, np.integer)):
        raise TypeError(f"timestep must be a positive real number of seconds, got {timestep!r}")
    if not (math.isfinite(float(timestep)) and float(timestep) > 0):
        raise ValueError(f"timestep must be a finite number > 0 seconds, got {timestep!r}")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
    if not isinstance(name, str) or not name or not all(c.isalnum() or c in "_-." for c in name):
        raise ValueError(f"name must be a non-empty string of letters, digits, '_', '-' or '.', got {name!r}")
    if isinstance(radius, bool) or not (isinstance(radius, (int, float)) and math.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be a finite number > 0 metres, got {radius!r}")
    if isinstance(tiny, bool) or not (isinstance(tiny, (int, float)) and 1e-15 < tiny <= 1e-6):
        raise ValueError(f"tiny must be a number in (1e-15, 1e-6], got {tiny!r}")
    for law, what in ((tree.contact, "contact"), (tree.limits, "limits")):
        if law is not None:
            raise NotImplementedError(f"to_mjcf: the tree has a {what} law ({type(law).__name__}), which MJCF cannot "
                                      "state (MuJoCo's contact and limits are constraints, not penalties); write "
                                      f"the tree without it: {type(tree).__name__}(..., {what}=None) and no "
                                      f"{'contact points' if what == 'contact' else 'joint ranges'}")
    for k, mu in enumerate(tree.muscles):
        if type(mu).tension is not Muscle.tension:
            raise NotImplementedError(f"to_mjcf: muscle {k} is a {type(mu).__name__}, whose tension law MJCF cannot "
                                      "state; only lagrange.Muscle's (activation x strength) is written")
    sites = {}  # body -> [(name, point)]
    for k, mu in enumerate(tree.muscles):
        for i, (b, x) in enumerate(zip(mu.bodies, _concrete(mu.points, f"muscle {k}.points"))):
            sites.setdefault(b, []).append((f"m{k}_{i}", x))
    gravity = _concrete(tree.gravity, f"{type(tree).__name__}.gravity")
    lines = [f'<mujoco model="{name}">',
             '  <compiler angle="radian" inertiafromgeom="false" autolimits="false"/>',
             f'  <option timestep="{_num(timestep)}" integrator="{integrator}" gravity="{_vec(gravity)}"/>',
             "  <custom>",
             '    <numeric name="matrix_inv_iterations" data="0"/>',
             "  </custom>",
             "  <worldbody>"]
    first = np.cumsum([0] + [len(b.joints) for b in tree.bodies])
    children = {i: [c for c, p in enumerate(tree.parents) if p == i] for i in (WORLD, *range(len(tree.bodies)))}

    def body(b: int, indent: str) -> None:
        bd = tree.bodies[b]
        label = bd.name if bd.name else f"body {b}"
        named = f' name="{bd.name}"' if bd.name else ""
        turn = "" if bd.quat == (1.0, 0.0, 0.0, 0.0) else f' quat="{_vec(bd.quat)}"'
        lines.append(f'{indent}<body{named} pos="{_vec(_concrete(bd.pos, f"{label}.pos"))}"{turn}>')
        inner = indent + "  "
        for k, j in enumerate(bd.joints):
            lines.append(inner + _joint(tree, int(first[b]) + k, j, b))
        lines.extend(inner + line for line in _inertial(bd, label, tiny))
        tip = np.zeros(3) if bd.tip is None else _concrete(bd.tip, f"{label}.tip")
        shape = (f'type="capsule" fromto="{_vec(np.concatenate([np.zeros(3), tip]))}" size="{_num(radius)}"'
                 if np.any(tip != 0) else f'type="sphere" size="{_num(2 * radius)}"')
        lines.append(f'{inner}<geom name="geom{b}" {shape} contype="0" conaffinity="0"/>')
        for site, x in sites.get(b, []):
            lines.append(f'{inner}<site name="{site}" pos="{_vec(x)}"/>')
        for c in children[b]:
            body(c, inner)
        lines.append(f"{indent}</body>")

    for root in children[WORLD]:
        body(root, "    ")
    lines.append("  </worldbody>")
    if tree.muscles:
        lines.append("  <tendon>")
        for k, mu in enumerate(tree.muscles):
            lines.append(f'    <spatial name="m{k}">')
            lines.extend(f'      <site site="m{k}_{i}"/>' for i in range(len(mu.bodies)))
            lines.append("    </spatial>")
        lines.append("  </tendon>")
    if tree.motors or tree.muscles:
        lines.append("  <actuator>")
        for k, mo in enumerate(tree.motors):
            r = mo.control_range
            limit = 'ctrllimited="false"' if r is None else f'ctrllimited="true" ctrlrange="{_vec(r)}"'
            gear = _num(_concrete(mo.gear, "Motor.gear"))
            if not isinstance(mo, AffineActuator):
                lines.append(f'    <motor name="u{k}" joint="q{mo.joint}" gear="{gear}" {limit} forcelimited="false"/>')
                continue
            f = mo.force_range
            force = 'forcelimited="false"' if f is None else f'forcelimited="true" forcerange="{_vec(f)}"'
            lines.append(f'    <general name="u{k}" joint="q{mo.joint}" gear="{gear}" {limit} {force} gaintype="fixed" '
                         f'gainprm="{_num(_concrete(mo.gain, "AffineActuator.gain"))}" biastype="affine" '
                         f'biasprm="{_vec(_concrete(mo.bias, "AffineActuator.bias"))}"/>')
        for k, mu in enumerate(tree.muscles):
            gain = -float(_concrete(mu.strength, f"muscle {k}.strength"))
            lines.append(f'    <general name="u{len(tree.motors) + k}" tendon="m{k}" ctrllimited="true" '
                         f'ctrlrange="0 1" gaintype="fixed" gainprm="{_num(gain)}" biastype="none"/>')
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


def _inertial(bd, label: str, tiny: float) -> list[str]:
    """The body's ``<inertial>`` (none for a massless body without joints): ``diaginertia`` for a diagonal inertia,
    ``fullinertia`` otherwise; a moving body's zero mass or principal moment written as ``tiny``."""
    mass = float(_concrete(bd.mass, f"{label}.mass"))
    J = _concrete(bd.inertia, f"{label}.inertia")
    if not (mass > 0 or np.any(J != 0) or bd.joints):
        return []
    com = _vec(_concrete(bd.com, f"{label}.com"))
    if np.all(J == np.diag(np.diag(J))):
        moments = np.where(np.diag(J) > 0, np.diag(J), tiny) if np.min(np.diag(J)) < tiny else np.diag(J)
        inertia = f'diaginertia="{_vec(moments)}"'
    else:
        if np.min(np.linalg.eigvalsh(J)) < tiny:  # MuJoCo's lower bound on a moving body's principal inertia
            J = J + tiny * np.eye(3)
        inertia = f'fullinertia="{_vec((J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]))}"'
    return [f'<inertial pos="{com}" mass="{_num(mass if mass > 0 else tiny)}" {inertia}/>']


def _joint(tree: Tree, k: int, j, b: int) -> str:
    common = (f' damping="{_num(_concrete(j.damping, f"joint {k}.damping"))}"'
              f' armature="{_num(_concrete(j.armature, f"joint {k}.armature"))}"')
    stiffness = float(_concrete(j.stiffness, f"joint {k}.stiffness"))
    if isinstance(j, (Hinge, Slide)):
        kind = "hinge" if isinstance(j, Hinge) else "slide"
        spring = (f' stiffness="{_num(stiffness)}" springref="{_num(_concrete(j.springref, f"joint {k}.springref"))}"'
                  if stiffness else "")
        return (f'<joint name="q{k}" type="{kind}" axis="{_vec(j.axis)}" pos="{_vec(j.pos)}"'
                f' ref="{_num(j.ref)}" limited="false"{common}{spring}/>')
    if stiffness and isinstance(j, DFlexBall):
        raise NotImplementedError(f"to_mjcf: joint {k} is a DFlexBall with a spring (DFlex's sin(theta/2) law), which "
                                  "MJCF cannot state (MuJoCo's ball spring is the rotation vector's): use a Ball")
    if stiffness:  # MJCF has no rest pose for a ball's or a free joint's spring but the body as written
        rest = (np.array([1.0, 0, 0, 0]) if isinstance(j, Ball) else
                np.concatenate([_concrete(tree.bodies[b].pos, "pos"), np.asarray(tree.bodies[b].quat)]))
        if j.springref is not None and not np.allclose(_concrete(j.springref, f"joint {k}.springref"), rest,
                                                       rtol=0, atol=1e-15):
            raise NotImplementedError(
                f"to_mjcf: joint {k} ({type(j).__name__}) has a spring whose rest pose is not the body as written; "
                "MJCF cannot state one (set springref to the body's pose, or stiffness to 0)")
        common += f' stiffness="{_num(stiffness)}"'
    if isinstance(j, Ball):
        return f'<joint name="q{k}" type="ball" pos="{_vec(j.pos)}" limited="false"{common}/>'
    assert isinstance(j, Free)
    return f'<joint name="q{k}" type="free" limited="false"{common}/>'
