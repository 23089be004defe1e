"""Writing a spatial :class:`~lagrange.model.tree.Tree` as MJCF, so that ``from_mjcf(to_mjcf(tree))`` gives the tree
back.

One ``<body>`` per body, nested in its parent's, at its ``pos`` and ``quat``; an explicit ``<inertial>`` (the centre of
mass, the mass and ``fullinertia``, ``inertiafromgeom="false"``); its joints in order (``hinge`` and ``slide`` with
their axis, anchor, ``ref``, damping, armature and spring; ``ball``; ``free``), named ``q{k}`` in the tree's joint
order; a ``<motor>`` per motor with its gear and ``ctrlrange``; the tree's gravity. No geoms: the file carries the
dynamics, not a picture. MuJoCo rejects a moving body whose mass or principal inertia is below ``1e-15``: such a
value is written as ``tiny`` (default ``1e-12``), the only way the written model can differ from the tree.
"""

from __future__ import annotations

import jax
import numpy as np

from lagrange.model.joints import Ball, Free, Hinge, Slide
from lagrange.model.tree import WORLD, Tree

__all__ = ["tree_mjcf"]


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


def _joint(tree: Tree, k: int, j, b: int) -> str:
    common = (f' damping="{_num(_concrete(j.damping, f"joint {k}.damping"))}"'
              f' armature="{_num(_concrete(j.armature, f"joint {k}.armature"))}"')
    stiffness = float(_concrete(j.stiffness, f"joint {k}.stiffness"))
    if isinstance(j, (Hinge, Slide)):
        kind = "hinge" if isinstance(j, Hinge) else "slide"
        spring = (f' stiffness="{_num(stiffness)}" springref="{_num(_concrete(j.springref, f"joint {k}.springref"))}"'
                  if stiffness else "")
        pos = _vec(_concrete(j.pos, f"joint {k}.pos"))
        return (f'<joint name="q{k}" type="{kind}" axis="{_vec(j.axis)}" pos="{pos}"'
                f' ref="{_num(_concrete(j.ref, f"joint {k}.ref"))}" limited="false"{common}{spring}/>')
    if stiffness:  # MJCF has no rest pose for a ball's or a free joint's spring but the body as written
        rest = (np.array([1.0, 0, 0, 0]) if isinstance(j, Ball) else
                np.concatenate([_concrete(tree.bodies[b].pos, "pos"), _concrete(tree.bodies[b].quat, "quat")]))
        if j.springref is not None and not np.allclose(_concrete(j.springref, f"joint {k}.springref"), rest,
                                                       rtol=0, atol=1e-15):
            raise NotImplementedError(
                f"to_mjcf: joint {k} ({type(j).__name__}) has a spring whose rest pose is not the body as written; "
                "MJCF cannot state one (set springref to the body's pose, or stiffness to 0)")
        common += f' stiffness="{_num(stiffness)}"'
    if isinstance(j, Ball):
        pos = _vec(_concrete(j.pos, f"joint {k}.pos"))
        return f'<joint name="q{k}" type="ball" pos="{pos}" limited="false"{common}/>'
    assert isinstance(j, Free)
    return f'<joint name="q{k}" type="free" limited="false"{common}/>'


def tree_mjcf(tree: Tree, timestep: float, integrator: str, name: str, tiny: float) -> str:
    """The MJCF string of ``tree`` (arguments checked by :func:`lagrange.interop.mjcf.to_mjcf`)."""
    for law, name in ((tree.contact, "contact"), (tree.limits, "limits")):
        if law is not None:
            raise NotImplementedError(f"to_mjcf: the tree has a {name} law ({type(law).__name__}), which MJCF cannot "
                                      "state (MuJoCo's contact and limits are constraints, not penalties); write "
                                      f"the tree without it: Tree(..., {name}=None) and no "
                                      f"{'contact points' if name == 'contact' else 'joint ranges'}")
    gravity = _concrete(tree.gravity, "Tree.gravity")
    lines = [f'<mujoco model="{name}">',
             '  <compiler angle="radian" inertiafromgeom="false" autolimits="false"/>',
             f'  <option timestep="{_num(timestep)}" integrator="{integrator}" gravity="{_vec(gravity)}"/>',
             "  <worldbody>"]
    first = np.cumsum([0] + [len(b.joints) for b in tree.bodies])
    children = {i: [c for c, p in enumerate(tree.parents) if p == i] for i in (WORLD, *range(len(tree.bodies)))}

    def body(b: int, indent: str) -> None:
        bd = tree.bodies[b]
        label = bd.name if bd.name else f"body {b}"
        named = f' name="{bd.name}"' if bd.name else ""
        lines.append(f'{indent}<body{named} pos="{_vec(_concrete(bd.pos, f"{label}.pos"))}" '
                     f'quat="{_vec(_concrete(bd.quat, f"{label}.quat"))}">')
        inner = indent + "  "
        mass = float(_concrete(bd.mass, f"{label}.mass"))
        J = _concrete(bd.inertia, f"{label}.inertia")
        if mass > 0 or np.any(J != 0) or bd.joints:
            if np.min(np.linalg.eigvalsh(J)) < tiny:  # MuJoCo's lower bound on a moving body's principal inertia
                J = J + tiny * np.eye(3)
            full = (J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2])
            lines.append(f'{inner}<inertial pos="{_vec(_concrete(bd.com, f"{label}.com"))}" '
                         f'mass="{_num(mass if mass > 0 else tiny)}" fullinertia="{_vec(full)}"/>')
        for k, j in enumerate(bd.joints):
            lines.append(inner + _joint(tree, int(first[b]) + k, j, b))
        for c in children[b]:
            body(c, inner)
        lines.append(f"{indent}</body>")

    for root in children[WORLD]:
        body(root, "    ")
    lines.append("  </worldbody>")
    if tree.motors:
        lines.append("  <actuator>")
        for k, mo in enumerate(tree.motors):
            r = mo.control_range
            limit = 'ctrllimited="false"' if r is None else f'ctrllimited="true" ctrlrange="{_vec(r)}"'
            lines.append(f'    <motor name="u{k}" joint="q{mo.joint}" gear="{_num(_concrete(mo.gear, "Motor.gear"))}" '
                         f'{limit} forcelimited="false"/>')
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"
