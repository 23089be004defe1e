"""The SNU humanoid of the SHAC paper ("Humanoid MTU"): MASS's lower body with its 152 muscles, as DFlex's loader
reads it.

The assets are MASS's (Seunghwan Lee, Kyoungmin Lee, Moonseok Park and Jehee Lee, "Scalable Muscle-actuated Human
Simulation and Control", SIGGRAPH 2019; github.com/lsw9021/MASS at e44c2ef, Apache-2.0, copyright 2019 Seunghwan Lee),
shipped unchanged in ``lagrange/tasks/assets/snu/`` with their licence: ``human.xml`` (the skeleton) and
``muscle284.xml`` (the muscles). What is read, and how, follows the SHAC release's loader (NVlabs/DiffRL 6b8d695,
``utils/load_utils.py``, ``envs/snu_humanoid.py``, ``dflex/dflex/{model,sim}.py``, read point by point; none of its code
is copied):

===================  ==================================================================================================
bodies               the 11 lower-body nodes (Pelvis; Femur, Tibia, Talus, FootThumb, FootPinky of each leg), in file
                     order, 37 kg; each a box of the node's mass and size, its centre at the body transformation's
                     translation less the joint's, turned by the quaternion of the body's ``linear`` matrix; the
                     link frames sit at the joints and keep MASS's world axes (y up, facing +z)
joints               the pelvis a :class:`~lagrange.model.joints.Free` joint; femurs and tali balls; tibiae and toes
                     hinges about MASS's x with their ranges (knees [0, 2.3], toes [-0.6, 0.6]; the balls' are not
                     read). With ``ms`` the body's mass / 15: a spring of stiffness ``5 sqrt(ms)`` toward the rest
                     pose, damping 2 (the hinges' plus DFlex's limit damping ``10 ms``, applied at all times),
                     armature 0.05; outside its range a hinge gets ``1000 ms (bound - q)``
muscles              the 152 of the 284 units whose waypoints all lie on those bodies, in file order; each waypoint
                     in its body's link frame; the tension ``a * 0.36 f0`` (DFlex's ``str_scale`` 0.6 twice), with
                     no force-length, force-velocity or passive term (:class:`lagrange.Muscle`)
contact              the 8 corners of every box, radius 0 (the XML's ``contact="Off"`` ignored, as DFlex ignores it);
                     :class:`lagrange.PenaltyContact` ke 5e3, kd 2e3, kf 1e3, mu 0.5 on the ground z = 0
world                z up: MASS's (x, y, z) are the world's (y, z, x) at the start, the pelvis's quaternion
                     ``(0.5, 0.5, 0.5, 0.5)`` (DFlex's start: y up, turned 90 degrees about y to face +x); the
                     pelvis's joint at (0, 0, 1) m
===================  ==================================================================================================

DFlex's quirks, and the options that keep or drop them:

- ``dflex_inertia=True`` (DFlex's): a box's inertia turned into its link's frame elementwise, ``R * I * R^T`` with
  NumPy's ``*``: ``diag(R_ii^2 I_ii)``, no products of inertia. ``False``: the rigid body's ``R I R^T``. On the femur
  the two differ by up to 1.5e-3 kg m^2 off the diagonal (0.1067, 0.0209, 0.1048 against DFlex's 0.1055, 0.0208,
  0.1036 on it).
- ``dflex_ball_spring=True`` (DFlex's): the balls' springs are DFlex's ``-ke sin(theta/2) axis``
  (:class:`~lagrange.model.joints.DFlexBall`), about half MuJoCo's rotation-vector spring near rest. ``False``:
  :class:`lagrange.Ball`'s, MuJoCo's.
- Kept as DFlex reads them, with no option: the femurs' body matrices are not orthonormal (their third rows start
  -0.21 and 0.21); their quaternion is DFlex's (the largest-diagonal branch of its ``quat_from_matrix``, normalised),
  about a 6 degree tilt. The left toes are not a mirror of the right (FootThumbL sits where FootPinkyR's mirror
  would). Every box collides.
"""

from __future__ import annotations

import math
import pathlib
import xml.etree.ElementTree as ET

import numpy as np

from lagrange.math import spatial as al
from lagrange.model.contact import PenaltyContact
from lagrange.model.joints import Ball, DFlexBall, Free, Hinge
from lagrange.model.limits import PenaltyLimits
from lagrange.model.muscles import Muscle
from lagrange.model.tree import Body, Tree

__all__ = ["ASSETS", "BODIES", "snu_tree"]

ASSETS = pathlib.Path(__file__).parent / "assets" / "snu"
"""MASS's ``human.xml`` and ``muscle284.xml``, with their licence and attribution."""

BODIES = ("Pelvis", "FemurR", "TibiaR", "TalusR", "FootThumbR", "FootPinkyR",
          "FemurL", "TibiaL", "TalusL", "FootThumbL", "FootPinkyL")
"""The lower-body nodes DFlex's SNU task keeps (its ``filter``), in the file's order."""

STRENGTH_SCALE = 0.36
"""DFlex's muscle tension per unit of activation and of ``f0``: its ``str_scale`` 0.6, applied twice."""

START = (0.0, 0.0, 1.0)
"""The pelvis's joint at the start [m] (DFlex's (0, 1, 0), y up)."""

START_QUAT = (0.5, 0.5, 0.5, 0.5)
"""The pelvis's orientation at the start: MASS's (x, y, z) turned onto the world's (y, z, x)."""


def _numbers(text: str, n: int, where: str) -> np.ndarray:
    x = np.array([float(v) for v in text.split()], float)
    if x.shape != (n,):
        raise ValueError(f"snu_tree: {where} must hold {n} numbers, got {text!r}")
    return x


def dflex_quat(m: np.ndarray) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)`` DFlex's ``quat_from_matrix`` gives a 3x3 matrix (rows as written),
    normalised: from the trace where it is >= 0, else from the largest diagonal entry (MASS's matrices need only the
    first; DFlex's other two call an undefined function)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr >= 0:
        h = math.sqrt(tr + 1.0)
        w, h = 0.5 * h, 0.5 / h
        x, y, z = (m[2, 1] - m[1, 2]) * h, (m[0, 2] - m[2, 0]) * h, (m[1, 0] - m[0, 1]) * h
    else:
        i = int(np.argmax(np.diag(m)))
        if i != 0:
            raise NotImplementedError("snu_tree: a body matrix whose largest diagonal entry is not the first (DFlex's "
                                      "quat_from_matrix fails there)")
        h = math.sqrt(m[0, 0] - (m[1, 1] + m[2, 2]) + 1.0)
        x, h = 0.5 * h, 0.5 / h
        y, z, w = (m[0, 1] + m[1, 0]) * h, (m[2, 0] + m[0, 2]) * h, (m[2, 1] - m[1, 2]) * h
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def _box_inertia(mass: float, size: np.ndarray) -> np.ndarray:
    """A solid box's principal moments about its centre, ``m/12 (b^2 + c^2)`` ... (``size``: full edge lengths)."""
    x, y, z = size
    return mass / 12.0 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])


def _nodes(path: pathlib.Path) -> dict:
    """``{name: (parent, mass, size, body translation, body linear, joint type, joint translation, axis, lower,
    upper)}`` for every ``<Node>`` of ``human.xml``."""
    out = {}
    for node in ET.parse(path).getroot().findall("Node"):
        name = node.get("name")
        body, joint = node.find("Body"), node.find("Joint")
        bt, jt = body.find("Transformation"), joint.find("Transformation")
        where = f"{path.name} <Node name=\"{name}\">"
        out[name] = dict(parent=node.get("parent"), mass=float(body.get("mass")),
                         size=_numbers(body.get("size"), 3, f"{where} <Body size>"),
                         body_t=_numbers(bt.get("translation"), 3, f"{where} <Body translation>"),
                         body_R=_numbers(bt.get("linear"), 9, f"{where} <Body linear>").reshape(3, 3),
                         kind=joint.get("type"), joint_t=_numbers(jt.get("translation"), 3, f"{where} <Joint>"),
                         axis=joint.get("axis"), lower=joint.get("lower"), upper=joint.get("upper"))
    return out


def muscle_units(path: pathlib.Path = ASSETS / "muscle284.xml", bodies=BODIES):
    """The ``<Unit>`` s of ``muscle284.xml`` whose waypoints all lie on ``bodies``, in file order: ``[(name, f0,
    [(body name, p (3,) in MASS's rest pose)])]``."""
    units = []
    for unit in ET.parse(path).getroot().findall("Unit"):
        points = [(w.get("body"), _numbers(w.get("p"), 3, f"{path.name} <Unit name=\"{unit.get('name')}\">"))
                  for w in unit.findall("Waypoint")]
        if all(b in bodies for b, _ in points):
            units.append((unit.get("name"), float(unit.get("f0")), points))
    return units


def snu_tree(*, dflex_inertia: bool = True, dflex_ball_spring: bool = True, muscles: bool = True) -> Tree:
    """DFlex's SNU humanoid (the module docstring): 11 bodies, ``nq = 29``, ``nv = 24``, 152 muscles (the controls
    are their activations, clamped into [0, 1]).

    Args:
        dflex_inertia: DFlex's elementwise turn of the boxes' inertias (``False``: the rigid body's ``R I R^T``).
        dflex_ball_spring: DFlex's ball springs ``-ke sin(theta/2) axis`` (``False``: MuJoCo's rotation vector).
        muscles: the 152 muscles (``False``: none, and no control).
    """
    nodes = _nodes(ASSETS / "human.xml")
    index = {name: k for k, name in enumerate(BODIES)}
    bodies, limited = [], []
    for name in BODIES:
        nd = nodes[name]
        ms = nd["mass"] / 15.0
        quat = dflex_quat(nd["body_R"])
        R = np.asarray(al.quat_to_matrix(quat, np))
        I_box = _box_inertia(nd["mass"], nd["size"])
        inertia = np.diag(np.diag(R) ** 2 * I_box) if dflex_inertia else R @ np.diag(I_box) @ R.T
        centre = nd["body_t"] - nd["joint_t"]
        half = nd["size"] / 2
        corners = [tuple(centre + R @ (half * np.array(s))) + (0.0,)
                   for s in np.array(np.meshgrid(*[[-1.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T]
        common = dict(stiffness=5.0 * math.sqrt(ms), armature=0.05, name=name)
        if nd["kind"] == "Free":
            joint = Free(name=name)
            place = dict(parent=-1, pos=START, quat=START_QUAT)
        else:
            parent = index[nd["parent"]]
            place = dict(parent=parent, pos=nd["joint_t"] - nodes[nd["parent"]]["joint_t"])
            if nd["kind"] == "Ball":
                joint = (DFlexBall if dflex_ball_spring else Ball)(damping=2.0, **common)
            elif nd["kind"] == "Revolute":
                rng = (float(nd["lower"]), float(nd["upper"]))
                joint = Hinge(_numbers(nd["axis"], 3, f"{name} axis"), damping=2.0 + 10.0 * ms, range=rng, **common)
                limited.append(1000.0 * ms)
            else:
                raise NotImplementedError(f"snu_tree: {name}'s joint type {nd['kind']!r}")
        bodies.append(Body(nd["mass"], inertia, centre, joints=[joint], contacts=corners, name=name, **place))
    units = muscle_units() if muscles else []
    muscle_list = [Muscle([(index[b], p - nodes[b]["joint_t"]) for b, p in points], STRENGTH_SCALE * f0, name=name)
                   for name, f0, points in units]
    return Tree(bodies, (0.0, 0.0, -9.81), muscles=muscle_list, contact=PenaltyContact(5e3, 2e3, 1e3, 0.5),
                limits=PenaltyLimits(np.array(limited), 0.0))
