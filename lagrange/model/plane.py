"""Whether a tree moves in one plane, from its static structure: every joint a hinge or a slide, the hinges turning
about one common axis and the slides moving across it (:attr:`lagrange.Tree.planar`, which the dispatch of
:mod:`lagrange.dynamics` reads to hand the tree to the planar backend, :mod:`lagrange.planar`).

The bodies' orientations and the joints' axes are static, so this is decided while tracing, before any parameter
is known: a tree that moves in a plane is planar whatever its masses and lengths.
"""

from __future__ import annotations

import functools

import numpy as np

from lagrange.math.spatial import quat_to_matrix
from lagrange.model.joints import Hinge, Slide

__all__ = ["TOLERANCE", "normal", "rotations"]

TOLERANCE = 1e-9
"""How far from parallel (a hinge's axis) or from the plane (a slide's) a unit axis may be [rad]: MJCF's axes,
written to a few digits and turned by body orientations, agree to about 1e-16."""


def rotations(tree) -> tuple[np.ndarray, ...]:
    """Every body's orientation in the world as written (its joints at ``ref``), static: ``R_parent R(quat)``."""
    out: list[np.ndarray] = []
    for b, body in enumerate(tree.bodies):
        R = quat_to_matrix(np.asarray(body.quat, float), np)
        R = R if tree.parents[b] < 0 else out[tree.parents[b]] @ R
        for target in (0.0, 1.0, -1.0):  # a quarter or half turn's round-off: exact
            R[np.abs(R - target) < 1e-15] = target
        out.append(R)
    return tuple(out)


def normal(tree) -> tuple[float, float, float] | None:
    """The unit normal ``Y`` of the plane the tree moves in (oriented so that its largest component is positive: the
    world's ``+y`` for a tree in the x-z plane), or ``None`` where the tree is not planar: a ball or free joint,
    hinges about axes more than :data:`TOLERANCE` from parallel, a slide out of the plane."""
    joints = tuple((type(j), tuple(getattr(j, "axis", ())), tree.joint_body[k]) for k, j in enumerate(tree.joints))
    return _normal(tuple((tuple(b.quat), b.parent) for b in tree.bodies), tree.parents, joints)


@functools.lru_cache(maxsize=512)
def _normal(bodies, parents, joints):
    if any(kind not in (Hinge, Slide) for kind, _, _ in joints):
        return None
    R = []
    for b, (quat, _) in enumerate(bodies):
        r = quat_to_matrix(np.asarray(quat, float), np)
        R.append(r if parents[b] < 0 else R[parents[b]] @ r)
    hinges = [R[b] @ np.asarray(a) for kind, a, b in joints if kind is Hinge]
    slides = [R[b] @ np.asarray(a) for kind, a, b in joints if kind is Slide]
    if hinges:
        n = hinges[0]
        if any(np.linalg.norm(np.cross(a, n)) > TOLERANCE for a in hinges[1:]):
            return None
    else:  # slides only: the plane they span, else (one direction) the first of y, z, x across every slide
        crossed = [np.cross(a, b) for a in slides for b in slides if np.linalg.norm(np.cross(a, b)) > TOLERANCE]
        candidates = [c / np.linalg.norm(c) for c in crossed[:1]] + [np.eye(3)[k] for k in (1, 2, 0)]
        n = next((c for c in candidates if all(abs(a @ c) <= TOLERANCE for a in slides)), None)
        if n is None:  # slides along three independent directions
            return None
    if any(abs(a @ n) > TOLERANCE for a in slides):
        return None
    n = n / np.linalg.norm(n)
    if n[int(np.argmax(np.abs(n)))] < 0:
        n = -n
    return tuple(0.0 if abs(x) < 1e-15 else float(x) for x in n)
