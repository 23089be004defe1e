"""Writing MJCF: a chain (or a spatial tree, :mod:`~lagrange.interop.mjcf.tree_writer`) as a model string that
MuJoCo, MJX and Brax simulate exactly.

:func:`to_mjcf` returns the model as an XML string; MuJoCo, MJX and Brax load it with their own
readers::

    import mujoco

    from lagrange import systems
    from lagrange.interop.mjcf import to_mjcf

    model = mujoco.MjModel.from_xml_string(to_mjcf(systems.acrobot(), timestep=0.01))

Writing needs neither MuJoCo nor Brax. :func:`to_mjcf` writes one ``<body>`` per link, nested in its parent's (a
link of the world in ``<worldbody>``). Our planar x-z conventions map onto MuJoCo's 3D frames as follows:

- Every body frame is the link's frame: origin at the joint, local ``-z`` along the link
  direction ``d(phi)`` and local ``+x`` along the normal ``e(phi)``. Body ``i`` sits at its ``attach`` point
  ``(x, 0, z)`` in its parent's frame (default ``(0, 0, -length_parent)``), turned by the link's ``offset`` about
  ``(0, -1, 0)``.
- A revolute joint is a ``hinge`` about ``(0, -1, 0)`` (``(0, 1, 0)`` for ``sense=-1``): positive ``q`` turns ``d``
  from ``(0, -1)`` towards ``+x``, as :func:`lagrange.kinematics.positions` does.
- A prismatic joint is a ``slide`` along ``e(phi_{i-1} + axis)``: ``(cos a, 0, sin a)`` in its own
  body's frame with ``a = axis - offset``.
- Each body carries an explicit ``<inertial>`` (``inertiafromgeom="false"``): the link's mass
  at ``(com_normal, 0, -com)`` and ``diaginertia="I I I"`` with ``I`` the planar moment about the centre
  of mass. Every hinge turns about the body ``y`` axis, so angular velocities stay along ``y``
  and only the ``y`` moment ever enters the dynamics; the other two are set equal to it only
  because MuJoCo requires a positive-definite inertia that satisfies the triangle inequality.
  MuJoCo also rejects a moving body whose mass or inertia is below ``1e-15``: a zero mass or
  a zero moment is written as ``tiny`` (default ``1e-12``). The exported dynamics then differ
  from the chain's by at most ``tiny`` times a squared lever arm, and not at all for a zero
  moment on a body that cannot rotate (e.g. a cart below no revolute joint).
- Joint ``damping``, ``armature``, ``stiffness`` and ``springref`` are the joint's own; each actuated joint gets one
  ``<motor>`` with the link's ``gear``, its ``control_range`` as ``ctrlrange`` (limited only
  where the link has one) and no force limits.
- Geoms (capsules along each link, spheres for zero-length links) are for looking only:
  ``contype="0" conaffinity="0"``, and they carry no mass because the inertials are explicit.
- ``<custom><numeric name="matrix_inv_iterations" data="0"/></custom>`` makes Brax's
  generalized pipeline solve with the exact mass matrix (its default approximates the inverse
  by Newton-Schulz iterations), so Brax, MuJoCo and :class:`lagrange.SemiImplicitEuler` agree
  step for step.
"""

from __future__ import annotations

import math

import jax
import numpy as np

from lagrange.chain import Chain
from lagrange.interop.mjcf.tree_writer import tree_mjcf
from lagrange.model.tree import Tree

INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
"""The MuJoCo integrators :func:`to_mjcf` accepts (Brax loads only ``"Euler"``)."""


def _num(x: float) -> str:
    """A float written so that MuJoCo reads back exactly the same double."""
    x = float(x)
    return "0" if x == 0.0 else repr(x)


def _vec(*xs) -> str:
    return " ".join(_num(x) for x in xs)


def _values(chain: Chain, name: str):
    x = getattr(chain, name)
    if x is None:
        return None
    if isinstance(x, jax.core.Tracer):
        raise TypeError(f"to_mjcf needs concrete parameters; Chain.{name} is traced (call it outside jit/grad)")
    return np.asarray(x, dtype=float)


def to_mjcf(
    chain: Chain | Tree,
    timestep: float = 0.01,
    integrator: str = "Euler",
    name: str = "chain",
    *,
    radius: float = 0.02,
    tiny: float = 1e-12,
) -> str:
    """The chain or tree as an MJCF model string, for ``mujoco.MjModel.from_xml_string`` or ``brax.io.mjcf.loads``.

    A :class:`~lagrange.model.tree.Tree` is written body for body (:mod:`~lagrange.interop.mjcf.tree_writer`), so that
    :func:`~lagrange.interop.mjcf.from_mjcf` reads it back (``tree=True`` for a planar one); ``radius`` then has no
    use (no geoms are written).

    Args:
        chain: the :class:`~lagrange.chain.Chain` or :class:`~lagrange.model.tree.Tree` (concrete parameters, not
        traced). timestep: MuJoCo's ``option/timestep`` [s], finite and > 0.
        integrator: one of ``"Euler"`` (MuJoCo's semi-implicit Euler, the one Brax loads and
            :class:`lagrange.SemiImplicitEuler` reproduces), ``"RK4"``, ``"implicit"``,
            ``"implicitfast"``.
        name: the model's name (letters, digits, ``_-.``).
        radius: radius [m] of the visual capsules, > 0; it has no effect on the dynamics.
        tiny: the value written for a zero mass or zero moment of inertia, which MuJoCo
            rejects; must be in ``(1e-15, 1e-6]``.

    Returns:
        The MJCF XML as a string. Joint ``i`` is named ``q{i}``, body ``i`` ``link{i}``,
        actuator ``k`` ``u{k}`` (in the order of ``chain.actuated``), so MuJoCo's ``qpos``,
        ``qvel`` and ``ctrl`` line up with ``q``, ``qd`` and ``u``.
    """
    if not isinstance(chain, (Chain, Tree)):
        raise TypeError(f"chain must be a lagrange.chain.Chain or a lagrange.Tree, got {type(chain).__name__}")
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
    if isinstance(chain, Tree):
        return tree_mjcf(chain, float(timestep), integrator, name, tiny)

    mass = _values(chain, "mass")
    length = _values(chain, "length")
    com = _values(chain, "com")
    inertia = _values(chain, "inertia")
    damping = _values(chain, "damping")
    armature = _values(chain, "armature")
    gear = _values(chain, "gear")
    gravity = _values(chain, "gravity")
    g = 0.0 if gravity is None else float(gravity)

    lines = [
        f'<mujoco model="{name}">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="false"/>',
        f'  <option timestep="{_num(timestep)}" integrator="{integrator}" gravity="{_vec(0, 0, -g)}"/>',
        "  <custom>",
        '    <numeric name="matrix_inv_iterations" data="0"/>',
        "  </custom>",
        "  <worldbody>",
    ]
    com_normal = _values(chain, "com_normal")
    attach = dict(zip(chain.attached, [] if chain.attach is None else _values(chain, "attach")))
    stiffness, springref = _values(chain, "stiffness"), _values(chain, "springref")

    def body(i: int, indent: str) -> None:
        p = chain.parents[i]
        if i in attach:  # (x, z) in the parent's frame (the world's for a link of the world)
            pos = _vec(attach[i][0], 0, attach[i][1])
        else:
            pos = _vec(0, 0, -length[p]) if p >= 0 else _vec(0, 0, 0)
        offset = chain.offsets[i]
        turn = f' axisangle="{_vec(0, -1, 0, offset)}"' if offset != 0.0 else ""
        lines.append(f'{indent}<body name="link{i}" pos="{pos}"{turn}>')
        inner = indent + "  "
        if chain.joints[i] == "revolute":
            kind, axis = "hinge", _vec(0, -chain.senses[i], 0)
        else:  # the axis in this body's frame, turned by the offset against the parent's
            a = chain.axes[i] - offset
            kind, axis = "slide", _vec(math.cos(a), 0, math.sin(a))
        attrs = f'name="q{i}" type="{kind}" pos="0 0 0" axis="{axis}" limited="false"'
        attrs += f' damping="{_num(0.0 if damping is None else damping[i])}"'
        attrs += f' armature="{_num(0.0 if armature is None else armature[i])}"'
        if stiffness is not None and stiffness[i] != 0:
            attrs += f' stiffness="{_num(stiffness[i])}" springref="{_num(springref[i])}"'
        lines.append(f"{inner}<joint {attrs}/>")
        m = mass[i] if mass[i] > 0 else tiny
        moment = inertia[i] if inertia[i] > 0 else tiny
        lines.append(
            f'{inner}<inertial pos="{_vec(0.0 if com_normal is None else com_normal[i], 0, -com[i])}" mass="{_num(m)}" '
            f'diaginertia="{_vec(moment, moment, moment)}"/>'
        )
        if length[i] > 0:
            shape = f'type="capsule" fromto="{_vec(0, 0, 0, 0, 0, -length[i])}" size="{_num(radius)}"'
        else:
            shape = f'type="sphere" size="{_num(2 * radius)}"'
        lines.append(f'{inner}<geom name="geom{i}" {shape} contype="0" conaffinity="0"/>')
        for c in chain.children(i):
            body(c, inner)
        lines.append(f"{indent}</body>")

    for root in chain.children(-1):
        body(root, "    ")
    lines.append("  </worldbody>")
    if chain.actuated:
        lines.append("  <actuator>")
        for k, j in enumerate(chain.actuated):
            r = None if chain.control_ranges is None else chain.control_ranges[k]
            limit = 'ctrllimited="false"' if r is None else f'ctrllimited="true" ctrlrange="{_vec(*r)}"'
            lines.append(f'    <motor name="u{k}" joint="q{j}" gear="{_num(gear[k])}" {limit} forcelimited="false"/>')
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"
