"""DFlex's 3-D bodies as its MJCF loader builds them (NVlabs/DiffRL ``utils/load_utils.py``, ``parse_mjcf``, and
``dflex/dflex/model.py``), from the SHAC release's ``ant.xml`` and ``humanoid.xml``: every sphere and capsule at
density 1000 with DFlex's (ODE's) capsule inertia, each MJCF body a :class:`lagrange.Body` with its hinges (DFlex's
one link per joint turns the same way), the loaders' joint parameters, contact and limit laws. The tasks on them:
:mod:`lagrange.tasks.locomotion3d`.
"""

import math

import numpy as np

from lagrange.model.contact import PenaltyContact
from lagrange.model.joints import Free, Hinge
from lagrange.model.limits import PenaltyLimits
from lagrange.tasks.locomotion import DENSITY, LIMIT_KD, LIMIT_KE, capsule_mass_and_inertia
from lagrange.model.tree import Body, Motor, Tree

__all__ = ["ant_tree", "dflex_body", "humanoid_tree"]


def _sphere(centre, radius: float):
    m = DENSITY * 4.0 / 3.0 * math.pi * radius**3
    return m, np.asarray(centre, float), 0.4 * m * radius**2 * np.eye(3), [(*map(float, centre), radius)]


def _capsule(a, b, radius: float):
    a, b = np.asarray(a, float), np.asarray(b, float)
    length = float(np.linalg.norm(b - a))
    m, transverse = capsule_mass_and_inertia(radius, length)
    ms = _sphere(a, radius)[0]  # the two end caps
    axial = (0.5 * (m - ms) + 0.4 * ms) * radius**2
    u = (b - a) / length
    inertia = transverse * (np.eye(3) - np.outer(u, u)) + axial * np.outer(u, u)
    return m, (a + b) / 2, inertia, [(*map(float, a), radius), (*map(float, b), radius)]


def dflex_body(spheres=(), capsules=(), **body) -> Body:
    """A :class:`lagrange.Body` made of spheres and capsules as DFlex's MJCF loader makes it: density 1000, DFlex's
    (ODE's) capsule inertia, the shapes' moments summed about their common centre of mass; the spheres' centres and the
    capsules' end points (with their radii) its contact points, spheres first.

    Args:
        spheres: ``(centre (3,), radius)`` pairs in the body's frame [m].
        capsules: ``(a (3,), b (3,), radius)``: a capsule from ``a`` to ``b`` (MJCF's ``fromto``) [m].
        body: the other arguments of :class:`lagrange.Body` (``joints``, ``parent``, ``pos``, ``name``).
    """
    shapes = [_sphere(c, r) for c, r in spheres] + [_capsule(a, b, r) for a, b, r in capsules]
    mass = sum(s[0] for s in shapes)
    com = sum(s[0] * s[1] for s in shapes) / mass
    inertia = sum(I + m * (float((c - com) @ (c - com)) * np.eye(3) - np.outer(c - com, c - com))
                  for m, c, I, _ in shapes)
    return Body(mass, inertia, com, contacts=[p for s in shapes for p in s[3]], **body)


# The asset's legs: the hip's body on the torso at (sx, sy) * 0.2 turning about z in [-40, 40] degrees, the ankle's one
# more (sx, sy) * 0.2 out turning about `axis` in `range` (degrees); the leg's capsule (sx, sy) * 0.2 long, the foot's
# (sx, sy) * 0.4, radius 0.08; in the order of the bodies (front left, front right, back left, back right).
_ANT_LEGS = (((1, 1), (-1, 1, 0), (30, 100)), ((-1, 1), (1, 1, 0), (-100, -30)),
             ((-1, -1), (-1, 1, 0), (-100, -30)), ((1, -1), (1, 1, 0), (30, 100)))


def ant_tree() -> Tree:
    """DFlex's ant (the SHAC release's ``envs/assets/ant.xml`` as its loader reads it): a torso (a sphere of radius
    0.25 and four capsules of radius 0.08 towards the hips) on a free joint, and four legs of two hinges each."""
    arm, kd, r, deg = 0.05, 1.0 + LIMIT_KD, 0.08, math.pi / 180
    bodies = [dflex_body([((0, 0, 0), 0.25)], [((0, 0, 0), (0.2 * sx, 0.2 * sy, 0), r) for (sx, sy), _, _ in _ANT_LEGS],
                         joints=[Free()], pos=(0.0, 0.0, 0.75), name="torso")]
    for (sx, sy), axis, (lo, hi) in _ANT_LEGS:
        out = (0.2 * sx, 0.2 * sy, 0.0)
        bodies.append(dflex_body(capsules=[((0, 0, 0), out, r)], parent=0, pos=out,
                                 joints=[Hinge((0, 0, 1), damping=kd, armature=arm, range=(-40 * deg, 40 * deg))]))
        bodies.append(dflex_body(capsules=[((0, 0, 0), (0.4 * sx, 0.4 * sy, 0), r)], parent=len(bodies) - 1, pos=out,
                                 joints=[Hinge(axis, damping=kd, armature=arm, range=(lo * deg, hi * deg))]))
    return Tree(bodies, gravity=(0.0, 0.0, -9.81), motors=[Motor(k, 200.0) for k in range(1, 9)],
                contact=PenaltyContact(4e4, 1e4, 3e3, 0.75), limits=PenaltyLimits(LIMIT_KE))


# The humanoid's joints as the asset writes them: (axis, anchor, range [deg], stiffness, damping, armature); the
# knees carry none of their own and get parse_mjcf's defaults (5, 0.1, 0.007) as DFlex's humanoid passes them.
_KNEE = ((0, -1, 0), (0, 0, 0.02), (-160, 2), 5.0, 0.1, 0.007)
_HUMANOID = (  # name, parent, pos, joints, spheres, capsules; the body quats (1, 0, -0.002, 0) ignored, as by DFlex
    ("lower_waist", 0, (-0.01, 0, -0.26), [((0, 0, 1), (0, 0, 0.065), (-45, 45), 20, 5, 0.02),
                                           ((0, 1, 0), (0, 0, 0.065), (-75, 30), 20, 5, 0.01)],
     [], [((0, -0.06, 0), (0, 0.06, 0), 0.06)]),
    ("pelvis", 1, (0, 0, -0.165), [((1, 0, 0), (0, 0, 0.1), (-35, 35), 10, 5, 0.01)],
     [], [((-0.02, -0.07, 0), (-0.02, 0.07, 0), 0.09)]),
    ("right_thigh", 2, (0, -0.1, -0.04), [((1, 0, 0), (0, 0, 0), (-25, 5), 10, 5, 0.01),
                                          ((0, 0, 1), (0, 0, 0), (-60, 35), 10, 5, 0.01),
                                          ((0, 1, 0), (0, 0, 0), (-80, 20), 20, 5, 0.01)],
     [], [((0, 0, 0), (0, 0.01, -0.34), 0.06)]),
    ("right_shin", 3, (0, 0.01, -0.403), [_KNEE], [], [((0, 0, 0), (0, 0, -0.3), 0.049)]),
    ("right_foot", 4, (0, 0, -0.39), [((0, 1, 0), (0, 0, 0.08), (-50, 50), 2, 1, 0.006),
                                      ((1, 0, 0.5), (0, 0, 0.08), (-50, 50), 2, 1, 0.006)],
     [], [((-0.07, -0.02, 0), (0.14, -0.04, 0), 0.027), ((-0.07, 0, 0), (0.14, 0.02, 0), 0.027)]),
    ("left_thigh", 2, (0, 0.1, -0.04), [((-1, 0, 0), (0, 0, 0), (-25, 5), 10, 5, 0.01),
                                        ((0, 0, -1), (0, 0, 0), (-60, 35), 10, 5, 0.01),
                                        ((0, 1, 0), (0, 0, 0), (-80, 20), 20, 5, 0.01)],
     [], [((0, 0, 0), (0, -0.01, -0.34), 0.06)]),
    ("left_shin", 6, (0, -0.01, -0.403), [_KNEE], [], [((0, 0, 0), (0, 0, -0.3), 0.049)]),
    ("left_foot", 7, (0, 0, -0.39), [((0, 1, 0), (0, 0, 0.08), (-50, 50), 2, 1, 0.006),
                                     ((1, 0, 0.5), (0, 0, 0.08), (-50, 50), 2, 1, 0.006)],
     [], [((-0.07, 0.02, 0), (0.14, 0.04, 0), 0.027), ((-0.07, 0, 0), (0.14, -0.02, 0), 0.027)]),
    ("right_upper_arm", 0, (0, -0.17, 0.06), [((2, 1, 1), (0, 0, 0), (-60, 60), 10, 5, 0.01),
                                              ((0, -1, 1), (0, 0, 0), (-60, 60), 10, 5, 0.01)],
     [], [((0, 0, 0), (0.16, -0.16, -0.16), 0.04)]),
    ("right_lower_arm", 9, (0.18, -0.18, -0.18), [((0, -1, 1), (0, 0, 0), (-90, 50), 2, 1, 0.006)],
     [((0.18, 0.18, 0.18), 0.04)], [((0.01, 0.01, 0.01), (0.17, 0.17, 0.17), 0.031)]),
    ("left_upper_arm", 0, (0, 0.17, 0.06), [((-2, 1, -1), (0, 0, 0), (-60, 60), 10, 5, 0.01),
                                            ((0, -1, -1), (0, 0, 0), (-60, 60), 10, 5, 0.01)],
     [], [((0, 0, 0), (0.16, 0.16, -0.16), 0.04)]),
    ("left_lower_arm", 11, (0.18, 0.18, -0.18), [((0, -1, -1), (0, 0, 0), (-90, 50), 2, 1, 0.006)],
     [((0.18, -0.18, 0.18), 0.04)], [((0.01, -0.01, 0.01), (0.17, -0.17, 0.17), 0.031)]),
)
# DFlex's humanoid: torque = 0.35 a x these, in the order of the hinges (its motor_strengths)
_HUMANOID_STRENGTH = (200, 200, 200, 200, 200, 600, 400, 100, 100, 200, 200, 600, 400, 100, 100, 100, 100, 200, 100,
                      100, 200)


def humanoid_tree() -> Tree:
    """DFlex's humanoid (the SHAC release's ``envs/assets/humanoid.xml`` as its loader reads it): a torso (two
    capsules and the head) on a free joint, the abdomen's three hinges, two legs of six and two arms of three; each
    hinge's stiffness (towards 0), damping (plus DFlex's limit damping 10) and armature from the asset."""
    deg = math.pi / 180
    bodies = [dflex_body([((0, 0, 0.19), 0.09)], [((0, -0.07, 0), (0, 0.07, 0), 0.07),
                                                   ((-0.01, -0.06, -0.12), (-0.01, 0.06, -0.12), 0.06)],
                         joints=[Free()], pos=(0.0, 0.0, 1.35), name="torso")]
    for name, parent, pos, joints, spheres, capsules in _HUMANOID:
        hinges = [Hinge(axis, anchor, stiffness=k, damping=kd + LIMIT_KD, armature=arm, range=(lo * deg, hi * deg))
                  for axis, anchor, (lo, hi), k, kd, arm in joints]
        bodies.append(dflex_body(spheres, capsules, joints=hinges, parent=parent, pos=pos, name=name))
    motors = [Motor(k + 1, 0.35 * g) for k, g in enumerate(_HUMANOID_STRENGTH)]
    return Tree(bodies, gravity=(0.0, 0.0, -9.81), motors=motors, contact=PenaltyContact(2e4, 5e3, 1e3, 0.75),
                limits=PenaltyLimits(LIMIT_KE))
