"""Reading a URDF robot as it ships into a :class:`~lagrange.model.tree.Tree`, without its meshes.

A URDF's dynamics are all in a few elements: each ``<link>``'s ``<inertial>`` (mass, centre of mass, inertia) and each
``<joint>``'s type, ``<origin>``, ``<axis>``, ``<limit>`` and ``<dynamics>``. :func:`from_urdf` reads them with Python's
XML parser, so that neither a mesh (``package://`` or relative paths, missing files) nor MuJoCo's compiler is needed,
and inertias are taken as written (MuJoCo's compiler refuses some that Pinocchio reads; one that is not physical is read
with a warning naming its link).

How a robot maps onto a tree (the same as MuJoCo's and Pinocchio's reading, so that ``q`` is MuJoCo's ``qpos`` of the
same robot):

- Every ``revolute`` or ``continuous`` joint is a :class:`~lagrange.model.joints.Hinge`, every ``prismatic`` one a
  :class:`~lagrange.model.joints.Slide`, about ``<axis>`` (default x) in the child link's frame; the child link is a
  :class:`~lagrange.model.tree.Body` placed by ``<origin xyz rpy>`` (rpy: roll about x, then pitch about y, then yaw
  about z, all fixed axes) and named after it. ``q = 0`` is the pose as written.
- A ``fixed`` joint merges its child link into the parent's body (mass, centre of mass and inertia composed); the root
  link is welded to the world, or with ``floating_base=True`` moves on a :class:`~lagrange.model.joints.Free` joint
  (MuJoCo's conventions: ``q[:7]`` its position and quaternion ``(w, x, y, z)``, ``qd[:6]`` its linear velocity in
  the world frame and its angular velocity in its own).
- Bodies and their joints come in depth-first order from the root, each link's children in the order their joints
  appear in the file.
- ``<dynamics damping>`` is the joint's damping. ``<dynamics friction>`` (Coulomb friction, not modelled) is dropped
  with a warning naming the joint. A ``<mimic>`` joint is read as an independent joint, as Pinocchio reads it by
  default, with a warning naming it.
- Every joint keeps its URDF name (:meth:`lagrange.Tree.joint_index` finds it; ``floating_base=True``'s free joint is
  ``"root_joint"``, as Pinocchio names it), every body its link's.
- ``motors=True`` (the default) drives every joint with a :class:`~lagrange.model.tree.Motor` of gear 1 (``u`` is the
  joints' torques and forces, in the order of ``qd``'s joint velocities), its control clamped to ``<limit effort>``
  where that is positive. ``motors`` may instead be a function of a joint's index that returns its actuator, e.g.
  ``lambda k: lg.AffineActuator.position(k, kp=5.0, kv=0.1)`` for MuJoCo's ``<position>`` servos on every joint.
- ``<limit lower upper>`` of a revolute or prismatic joint: ``limits="ignore"`` (the default, as Pinocchio's dynamics
  read them: no force from a limit), or a :class:`lagrange.PenaltyLimits` pressing each range.
- ``contact=PenaltyContact(...)``: the collision spheres (their centres, with their radii), boxes (their corners) and
  cylinders (the rims of their end faces, 8 points each) press the ground; a mesh collision geometry is refused by
  name. ``contact_points={"FL_FOOT": [(0, 0, 0, 0.016)]}`` gives a link's points by hand instead, ``(x, y, z,
  radius)`` in the link's frame (Solo12's and Go2's feet are meshes).
"""

from __future__ import annotations

import pathlib
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from lagrange.model.contact import PenaltyContact
from lagrange.model.joints import Free, Hinge, Slide
from lagrange.model.limits import PenaltyLimits
from lagrange.model.checks import check_points
from lagrange.model.tree import WORLD, Body, Motor, Tree

__all__ = ["from_urdf"]

_MOVING = {"revolute": Hinge, "continuous": Hinge, "prismatic": Slide}
_KINDS = (*_MOVING, "fixed", "floating", "planar")


class _Error(ValueError):
    pass


def _numbers(el, attr, n, default, where):
    text = None if el is None else el.get(attr)
    if text is None:
        if default is None:
            raise _Error(f"{where}: {attr} is required ({n} number{'s' if n > 1 else ''})")
        return np.array(default, float)
    what = "a finite number" if n == 1 else f"{n} finite numbers"
    try:
        x = np.array([float(v) for v in text.split()], float)
    except ValueError:
        raise _Error(f"{where}: {attr}=\"{text}\" must be {what}") from None
    if x.shape != (n,) or not np.all(np.isfinite(x)):
        raise _Error(f"{where}: {attr}=\"{text}\" must be {what}")
    return x


def _rpy(rpy):
    """URDF's fixed-axis roll, pitch, yaw as a rotation matrix ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    (cr, sr), (cp, sp), (cy, sy) = ((np.cos(a), np.sin(a)) for a in rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _quat(R):
    """The unit quaternion ``(w, x, y, z)``, ``w >= 0``, of a rotation matrix (Shepperd's method: from the largest of
    its four squares, so that no component is a small difference of near-equal terms)."""
    t = np.trace(R)
    k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        w = np.sqrt(1.0 + t) / 2
        q = [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]
    elif k == 1:
        x = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) / 2
        q = [(R[2, 1] - R[1, 2]) / (4 * x), x, (R[0, 1] + R[1, 0]) / (4 * x), (R[0, 2] + R[2, 0]) / (4 * x)]
    elif k == 2:
        y = np.sqrt(1.0 - R[0, 0] + R[1, 1] - R[2, 2]) / 2
        q = [(R[0, 2] - R[2, 0]) / (4 * y), (R[0, 1] + R[1, 0]) / (4 * y), y, (R[1, 2] + R[2, 1]) / (4 * y)]
    else:
        z = np.sqrt(1.0 - R[0, 0] - R[1, 1] + R[2, 2]) / 2
        q = [(R[1, 0] - R[0, 1]) / (4 * z), (R[0, 2] + R[2, 0]) / (4 * z), (R[1, 2] + R[2, 1]) / (4 * z), z]
    q = np.array(q)
    q = -q if q[0] < 0 else q
    return q / np.linalg.norm(q)


def _origin(el, where):
    o = el.find("origin")
    return _rpy(_numbers(o, "rpy", 3, (0, 0, 0), where)), _numbers(o, "xyz", 3, (0, 0, 0), where)


def _inertial(link, where):
    """``(mass, com, inertia about the com)`` in the link's frame; zeros without ``<inertial>``."""
    el = link.find("inertial")
    if el is None:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    R, c = _origin(el, where)
    m = el.find("mass")
    mass = float(_numbers(m, "value", 1, (0.0,), f"{where} <mass>")[0])
    if mass < 0:
        raise _Error(f"{where} <mass>: value must be >= 0, got {mass}")
    i = el.find("inertia")
    names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    v = {k: float(_numbers(i, k, 1, (0.0,), f"{where} <inertia>")[0]) for k in names}
    J = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
    return mass, c, R @ J @ R.T


def _compose(parts):
    """One body's mass, centre of mass and inertia about it from ``(mass, com, inertia)`` parts in its frame; entries
    below the round-off of the terms summed are exact zeros (a massless or point-mass part turned)."""
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass if mass > 0 else np.zeros(3)
    J, scale = np.zeros((3, 3)), 0.0
    for m, c, I in parts:
        d = c - com
        J += I + m * (d @ d * np.eye(3) - np.outer(d, d))
        scale += np.max(np.abs(I), initial=0.0) + m * (d @ d)
    J = (J + J.T) / 2
    J[np.abs(J) <= 16 * np.finfo(float).eps * scale] = 0.0
    return mass, com, J


def _points(link, R, p, where):
    """The link's collision spheres, boxes and cylinders as contact points ``(x, y, z, radius)`` in its body's frame
    (the link's frame turned by ``R`` and placed at ``p``)."""
    out = []
    for k, col in enumerate(link.findall("collision")):
        Rc, pc = _origin(col, f"{where} <collision> {k}")
        g = col.find("geometry")
        shape = None if g is None or not len(g) else g[0]
        here = f"{where} <collision> {k}"
        if shape is None:
            continue
        if shape.tag == "sphere":
            local = [(np.zeros(3), float(_numbers(shape, "radius", 1, None, here)[0]))]
        elif shape.tag == "box":
            half = _numbers(shape, "size", 3, None, here) / 2
            local = [(half * np.array(s), 0.0) for s in np.array(np.meshgrid(*[[-1, 1]] * 3)).T.reshape(-1, 3)]
        elif shape.tag == "cylinder":
            r = float(_numbers(shape, "radius", 1, None, here)[0])
            h = float(_numbers(shape, "length", 1, None, here)[0]) / 2
            a = np.arange(8) * np.pi / 4
            local = [(np.array([r * np.cos(t), r * np.sin(t), z]), 0.0) for z in (-h, h) for t in a]
        else:
            raise NotImplementedError(
                f"{here}: a <{shape.tag}> collision geometry cannot give contact points; contact=PenaltyContact(...) "
                "takes spheres, boxes and cylinders: read the robot without contact and give its bodies points by "
                "hand (lagrange.Body(..., contacts=[(x, y, z, radius), ...]))")
        for x, radius in local:
            out.append((*(R @ (Rc @ x + pc) + p).tolist(), radius))
    return out


def _check_inertia(name, mass, J, file):
    e = np.linalg.eigvalsh(J)
    tol = 1e-12 * max(1.0, float(np.max(np.abs(J))))
    if e[0] < -tol:
        raise _Error(f"link {name!r} has an inertia with a negative principal moment (principal moments {e.tolist()}"
                     "): lagrange needs positive semi-definite inertias, since a negative moment gives some motion a "
                     "negative kinetic energy (Pinocchio reads it as written)")
    if mass > 0 and (e[0] <= tol or e[0] + e[1] < e[2] - tol):
        warnings.warn(f"{file}: link {name!r} has an inertia that is not physical (principal moments {e.tolist()}: "
                      "not all positive, or two of them sum to less than the third); read as written, as Pinocchio "
                      "reads it (MuJoCo's compiler refuses it)", stacklevel=3)


def from_urdf(source, *, floating_base: bool = False, motors: bool | Callable[[int], Motor] = True,
              limits: str | PenaltyLimits = "ignore", contact: PenaltyContact | None = None,
              contact_links: Sequence[str] | None = None,
              contact_points: Mapping[str, Sequence[Sequence[float]]] | None = None,
              gravity=(0.0, 0.0, -9.81)) -> Tree:
    """A URDF robot as a :class:`~lagrange.model.tree.Tree` (the module docstring says how), its meshes never opened.

    Args:
        source: a path to a ``.urdf`` file, or the URDF text (a string starting with ``<``).
        floating_base: put a :class:`~lagrange.model.joints.Free` joint at the root (a robot that walks); ``False``
            welds the root link to the world.
        motors: ``True``: drive every joint with a motor of gear 1 (``u`` the joint torques and forces), clamped to
            its ``<limit effort>`` where positive; ``False``: no controls; a function ``k -> actuator`` of the index of
            each hinge or slide (the free joint of ``floating_base`` is joint 0 and gets none), e.g.
            ``lambda k: lg.AffineActuator.position(k, kp, kv)``.
        limits: ``"ignore"`` (no force from the joints' ``<limit lower upper>``) or a :class:`lagrange.PenaltyLimits`
            that presses them.
        contact: ``None``, or a :class:`lagrange.PenaltyContact` pressing the collision spheres, boxes and cylinders
            against the ground.
        contact_links: with ``contact``, the links whose collision geometry gives contact points (a quadruped's
            feet); ``None``: every link's, or with ``contact_points`` none but those.
        contact_points: with ``contact``, points given by hand for links whose collision geometry is a mesh: link
            name -> ``[(x, y, z, radius), ...]`` in the link's frame; they replace that link's collision geometry.
        gravity: the world's gravity vector [m/s^2].

    Returns:
        The tree: ``q`` is MuJoCo's ``qpos`` of the same robot, each body named after its link.

    Raises:
        ValueError: naming the file and the element, for a malformed file, a joint whose parent or child link does
            not exist, a link with two parent joints, a cycle, no root or several, a robot with no moving joint,
            ``floating_base=True`` on a robot whose root already floats, ``contact_links`` or ``contact_points``
            naming a link that does not exist, a point that is not finite or has a negative radius.
        TypeError: for ``motors`` neither a bool nor a function, a point that is not a sequence of numbers.
        NotImplementedError: for a ``planar`` joint, or with ``contact``, a mesh collision geometry.
    """
    if isinstance(source, str) and source.lstrip().startswith("<"):
        file, text = "the URDF text", source
    else:
        file = str(source)
        try:
            text = pathlib.Path(source).read_text()
        except OSError as e:
            raise ValueError(f"from_urdf: cannot read {file}: {e}") from None
    if not isinstance(limits, PenaltyLimits) and limits != "ignore":
        raise ValueError(f"from_urdf: limits must be \"ignore\" or a lagrange.PenaltyLimits, got {limits!r}")
    if contact is not None and not isinstance(contact, PenaltyContact):
        raise TypeError(f"from_urdf: contact must be None or a lagrange.PenaltyContact, got {type(contact).__name__}")
    if not (isinstance(motors, bool) or callable(motors)):
        raise TypeError(f"from_urdf: motors must be True, False or a function of a joint's index that returns its "
                        f"actuator, got {type(motors).__name__}")
    hand = {link: check_points(f"contact_points[{link!r}]", pts, owner="from_urdf", coords=("x", "y", "z"))
            for link, pts in (contact_points or {}).items()}
    try:
        return _read(text, file, floating_base, motors, limits, contact, contact_links, hand, gravity)
    except _Error as e:
        raise ValueError(f"from_urdf: {file}: {e}") from None


def _read(text, file, floating_base, motors, limits, contact, contact_links, hand, gravity):
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as e:
        raise _Error(f"not well-formed XML ({e})") from None
    if robot.tag != "robot":
        raise _Error(f"the root element is <{robot.tag}>, not <robot>")
    links = {}
    for el in robot.findall("link"):
        name = el.get("name")
        if not name:
            raise _Error("a <link> has no name")
        if name in links:
            raise _Error(f"two links are named {name!r}")
        links[name] = el
    parent_of, children = {}, {name: [] for name in links}
    for el in robot.findall("joint"):
        name, kind = el.get("name"), el.get("type")
        where = f"<joint name=\"{name}\">"
        if kind not in _KINDS:
            raise _Error(f"{where} has type={kind!r}; URDF's types are {', '.join(_KINDS)}")
        if kind == "planar":
            raise NotImplementedError(f"from_urdf: {file}: {where} is a planar joint, which lagrange does not read: "
                                      "write it as two slides and a hinge")
        ends = {}
        for end in ("parent", "child"):
            e = el.find(end)
            link = None if e is None else e.get("link")
            if link not in links:
                raise _Error(f"{where} names the {end} link {link!r}, which does not exist")
            ends[end] = link
        if ends["child"] in parent_of:
            first = parent_of[ends["child"]][0]
            raise _Error(f"{where}: link {ends['child']!r} is already the child of joint {first!r}"
                         " (a link has one parent joint; a closed loop is not a tree)")
        parent_of[ends["child"]] = (name, el, ends["parent"])
        children[ends["parent"]].append(ends["child"])
    for arg, named in (("contact_links", contact_links or ()), ("contact_points", hand)):
        missing = sorted(set(named) - set(links))
        if missing:
            raise _Error(f"{arg} names links that do not exist: {missing}; the links: {sorted(links)}")
    if contact_links is None and hand:
        contact_links = ()
    roots = [name for name in links if name not in parent_of]
    if len(roots) != 1:
        raise _Error("no link is the root (every link is some joint's child: a cycle)" if not roots else
                     f"{len(roots)} links have no parent joint ({', '.join(map(repr, roots))}); a robot has one root")

    inertials = {name: _inertial(el, f"<link name=\"{name}\">") for name, el in links.items()}
    floor = 1e-15 * max((float(np.max(np.abs(J))) for _, _, J in inertials.values()), default=0.0)
    bodies, motor_list, seen = [], [], set()
    parts = {}  # body index -> [(mass, com, inertia)], in the body's frame
    points = {}

    def visit(link, body, R, p):
        """Place ``link``, whose frame is ``(R, p)`` in body ``body``'s (WORLD: welded to the world)."""
        seen.add(link)
        where = f"<link name=\"{link}\">"
        m, c, J = inertials[link]
        J = np.where(np.abs(J) < floor, 0.0, J)  # the file's round-off (1e-20 beside 1e-5) read as zero
        if body != WORLD:
            parts[body].append((m, R @ c + p, R @ J @ R.T))
            if contact is not None and link in hand:
                points[body] += [(*(R @ np.array(x[:3]) + p).tolist(), x[3]) for x in hand[link]]
            elif contact is not None and (contact_links is None or link in contact_links):
                points[body] += _points(links[link], R, p, where)
        for child in children[link]:
            name, el, _ = parent_of[child]
            where = f"<joint name=\"{name}\">"
            Ro, po = _origin(el, where)
            Rc, pc = R @ Ro, R @ po + p
            kind = el.get("type")
            if kind == "fixed":
                visit(child, body, Rc, pc)
                continue
            if kind == "floating":
                if body != WORLD or floating_base:
                    raise _Error(f"{where} is a floating joint: " + (
                        "floating_base=True puts a free joint at the root, and this robot's root already floats: "
                        "drop floating_base" if floating_base else "only the root may float"))
                joint = Free(name=name)
            else:
                joint = _moving(el, kind, where, limits, file, name)
            bodies.append(dict(joints=(joint,), parent=body, pos=pc, quat=_quat(Rc), name=child))
            k = len(bodies) - 1
            parts[k], points[k] = [], []
            if callable(motors) and kind != "floating":
                motor_list.append(motors(k))  # body k's one joint is joint k
            elif motors and kind != "floating":
                lim = el.find("limit")
                effort = 0.0 if lim is None else float(_numbers(lim, "effort", 1, (0.0,), where)[0])
                motor_list.append(Motor(k, 1.0, (-effort, effort) if effort > 0 else None))
            visit(child, k, np.eye(3), np.zeros(3))

    root = roots[0]
    if floating_base:
        bodies.append(dict(joints=(Free(name="root_joint"),), parent=WORLD, pos=np.zeros(3),
                           quat=np.array([1.0, 0, 0, 0]), name=root))
        parts[0], points[0] = [], []
        visit(root, 0, np.eye(3), np.zeros(3))
    else:
        visit(root, WORLD, np.eye(3), np.zeros(3))
    unseen = [name for name in links if name not in seen]
    if unseen:
        raise _Error(f"links {unseen} cannot be reached from the root {root!r} (a cycle among their joints)")
    if not bodies:
        raise _Error("the robot has no moving joint (every joint is fixed): nothing to simulate")
    out = []
    for k, b in enumerate(bodies):
        mass, com, J = _compose(parts[k])
        _check_inertia(b["name"], mass, J, file)
        out.append(Body(mass, J, com, joints=b["joints"], parent=b["parent"], pos=b["pos"], quat=b["quat"],
                        contacts=points[k], name=b["name"]))
    law_limits = limits if isinstance(limits, PenaltyLimits) and any(
        j.range is not None for b in out for j in b.joints) else None
    law_contact = contact if any(b.contacts for b in out) else None
    if contact is not None and law_contact is None:
        warnings.warn(f"{file}: contact was given but no link has a collision sphere, box or cylinder; the robot "
                      "touches nothing", stacklevel=2)
    return Tree(out, gravity, motors=motor_list, limits=law_limits, contact=law_contact)


def _moving(el, kind, where, limits, file, name):
    axis = _numbers(el.find("axis"), "xyz", 3, (1.0, 0.0, 0.0), f"{where} <axis>")
    if not np.linalg.norm(axis) > 0:
        raise _Error(f"{where} <axis>: xyz must not be zero")
    dyn = el.find("dynamics")
    damping = float(_numbers(dyn, "damping", 1, (0.0,), f"{where} <dynamics>")[0])
    friction = float(_numbers(dyn, "friction", 1, (0.0,), f"{where} <dynamics>")[0])
    if damping < 0:
        raise _Error(f"{where} <dynamics>: damping must be >= 0, got {damping}")
    if friction != 0:
        warnings.warn(f"{file}: {where} has <dynamics friction=\"{friction}\"> (Coulomb friction), which lagrange "
                      "does not model: dropped", stacklevel=4)
    if el.find("mimic") is not None:
        warnings.warn(f"{file}: {where} mimics joint {el.find('mimic').get('joint')!r}; read as an independent joint, "
                      "as Pinocchio reads it by default", stacklevel=4)
    lim = el.find("limit")
    rng = None
    if kind != "continuous" and isinstance(limits, PenaltyLimits) and lim is not None and \
            lim.get("lower") is not None and lim.get("upper") is not None:
        lo, hi = (float(_numbers(lim, a, 1, None, f"{where} <limit>")[0]) for a in ("lower", "upper"))
        rng = (lo, hi) if lo < hi else None
    return _MOVING[kind](axis, damping=damping, range=rng, name=name)
