"""``from_urdf`` reads a URDF as it ships (no mesh opened) into a tree equal to Pinocchio's reading of the same file
(M, gravity, C qd, fixed base and floating base) and to MuJoCo's (``q = qpos``), and refuses bad files by element.

``tests/assets/arm.urdf``: a branched arm with mesh visuals that do not exist (``package://`` and relative paths), a
revolute, a continuous and a prismatic joint about tilted axes, rotated inertial frames, a fixed joint whose child
carries mass (merged), a massless tool link on a fixed joint, damping, a friction that is dropped, effort limits,
a box and a sphere for collision. Four robots of ``example-robot-data`` as they ship (``tests/assets/robots/``,
``examples/assets/solo12.urdf``; sources and licences in ``tests/assets/robots/README.md``): Panda (fixed joints merged,
a mimic joint), Kinova (continuous joints), Solo12 (a quadruped) and Romeo (a 31-joint humanoid with inertias that are
not physical). The whole package is ``python -m benchmarks.urdf_robots``."""

import pathlib
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop.urdf import from_urdf
from lagrange.kinematics import contact_point_positions
from tests.helpers import mujoco_terms, rel

ARM = pathlib.Path(__file__).resolve().parents[2] / "assets" / "arm.urdf"
SOLO12 = ARM.parents[2] / "examples" / "assets" / "solo12.urdf"
TIGHT = 1e-12  # float64 round-off on an arm of a few bodies (the errors measured are ~1e-16)


def _read(path=ARM, **kw):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*friction")
        return from_urdf(path, **kw)


@pytest.mark.parametrize("floating", [False, True], ids=["fixed", "floating"])
def test_the_arm_equals_pinocchio(floating):
    import pinocchio as pin

    from benchmarks.urdf_robots import compare

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*friction")
        r = compare(ARM, floating, states=3)
    assert (r["nv"], r["pinocchio_nv"]) == ((10, 10) if floating else (4, 4))
    assert r["M"] <= TIGHT and r["g"] <= TIGHT and r["Cqd"] <= TIGHT, r
    assert pin.buildModelFromUrdf(str(ARM)).nv == 4


ROBOTS = {"panda": "mimics joint 'panda_finger_joint1'", "kinova": None, "solo12": None,
          "romeo_small": "link 'RElbowYawLink' has an inertia that is not physical"}


@pytest.mark.parametrize("floating", [False, True], ids=["fixed", "floating"])
@pytest.mark.parametrize("robot", list(ROBOTS))
def test_robots_as_they_ship_equal_pinocchio(robot, floating):
    """M, the gravity forces and C qd equal Pinocchio's reading of the same file at random states, with a fixed base
    and with a free joint at the root; the mimic joint and the non-physical inertias are warned about."""
    from benchmarks.urdf_robots import compare

    path = SOLO12 if robot == "solo12" else ARM.parent / "robots" / f"{robot}.urdf"
    r = compare(path, floating, states=2)
    nv = dict(panda=9, kinova=6, solo12=12, romeo_small=31)[robot] + 6 * floating
    assert (r["nv"], r["pinocchio_nv"]) == (nv, nv)
    assert r["M"] <= TIGHT and r["g"] <= TIGHT and r["Cqd"] <= TIGHT, r  # measured <= 5e-14 (romeo's C qd)
    if ROBOTS[robot]:
        assert any(ROBOTS[robot] in w for w in r["warnings"]), r["warnings"]
    else:
        assert r["warnings"] == []


def test_q_is_mujocos_qpos_and_the_forces_are_its_own():
    import mujoco

    tree = _read(motors=False)
    model = mujoco.MjModel.from_xml_path(str(ARM))  # MuJoCo discards a URDF's visuals: it compiles this one
    assert [model.joint(i).name for i in range(model.njnt)] == ["shoulder", "elbow", "extend", "side_joint"]
    assert [b.name for b in tree.bodies] == ["upper", "fore", "slider", "side"]
    assert [j.name for j in tree.joints] == [model.joint(i).name for i in range(model.njnt)]
    assert tree.joint_index("extend") == 2 and tree.body_index("side") == 3
    assert _read(floating_base=True).joint_index("root_joint") == 0
    with pytest.raises(KeyError, match=r"no joint named 'knee'; its joints: \['shoulder', 'elbow'"):
        tree.joint_index("knee")
    rng = np.random.default_rng(3)
    q, qd = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
    M, bias, _ = mujoco_terms(model, q, qd, np.zeros(model.nu))
    assert rel(lg.mass_matrix(tree, jnp.asarray(q)), M) <= TIGHT
    assert rel(lg.bias_forces(tree, jnp.asarray(q), jnp.asarray(qd)), bias) <= TIGHT  # damping included


def test_what_is_read_and_what_is_warned_about():
    with pytest.warns(UserWarning, match=r"<joint name=\"side_joint\"> has <dynamics friction=\"0.2\">"):
        tree = from_urdf(ARM)
    # fixed joints merge: upper + flange (0.4 kg) in one body; the massless tool on the slider adds nothing
    assert np.isclose(float(tree.bodies[0].mass), 1.9) and np.isclose(float(tree.bodies[2].mass), 0.3)
    assert [float(j.damping) for j in tree.joints] == [0.3, 0.0, 0.0, 0.1]
    assert tree.m == 4 and tree.control_ranges == ((-50.0, 50.0), None, (-20.0, 20.0), (-5.0, 5.0))
    assert tree.limits is None and all(j.range is None for j in tree.joints)  # limits="ignore", as Pinocchio
    limited = _read(limits=lg.PenaltyLimits(1e3, 10.0))
    assert [j.range for j in limited.joints] == [(-2.0, 2.0), None, (0.0, 0.1), (-1.0, 1.0)]  # continuous: none
    touching = _read(contact=lg.PenaltyContact(2e4, 1e3, 1e3, 0.9), floating_base=True)
    assert [len(b.contacts) for b in touching.bodies] == [8, 0, 0, 1, 0]  # the base's box corners, the sphere
    assert touching.bodies[3].contacts[0][3] == 0.03
    mimic = ARM.read_text().replace('<axis xyz="0 1 1"/>', '<axis xyz="0 1 1"/><mimic joint="shoulder"/>')
    with pytest.warns(UserWarning, match=r"<joint name=\"elbow\"> mimics joint 'shoulder'; read as an independent"):
        _read(mimic)
    odd = ARM.read_text().replace('ixx="0.02" ixy="0.0" ixz="0.0" iyy="0.025"', 'ixx="0.002" ixy="0.0" ixz="0.0" '
                                  'iyy="0.025"')
    with pytest.warns(UserWarning, match=r"link 'upper' has an inertia that is not physical"):
        _read(odd)


BAD = {
    "missing link": (lambda s: s.replace('<child link="fore"/>', '<child link="forearm"/>'),
                     r"<joint name=\"elbow\"> names the child link 'forearm', which does not exist"),
    "two parents": (lambda s: s.replace('<child link="side"/>', '<child link="fore"/>'),
                    r"<joint name=\"side_joint\">: link 'fore' is already the child of joint 'elbow'"),
    "cycle": (lambda s: s.replace('</robot>', '<joint name="loop" type="fixed"><parent link="slider"/>'
                                  '<child link="base"/></joint></robot>'), r"no link is the root .*a cycle"),
    "malformed": (lambda s: s.replace("</robot>", ""), r"not well-formed XML"),
    "bad number": (lambda s: s.replace('<mass value="3.0"/>', '<mass value="three"/>'),
                   r"<link name=\"base\"> <mass>: value=\"three\" must be a finite number"),
    "no moving joint": (lambda s: s.replace('type="revolute"', 'type="fixed"').replace('type="continuous"',
                                                                                        'type="fixed"')
                        .replace('type="prismatic"', 'type="fixed"'), r"the robot has no moving joint"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_files_are_refused_naming_the_file_and_the_element(case):
    edit, message = BAD[case]
    with pytest.raises(ValueError, match=r"from_urdf: the URDF text: " + message):
        _read(edit(ARM.read_text()))
    with pytest.raises(ValueError, match=rf"from_urdf: cannot read {ARM.parent}/nothing.urdf"):
        from_urdf(ARM.parent / "nothing.urdf")


def test_a_root_that_already_floats_and_mesh_collisions_are_refused():
    free = ('<link name="world"/><joint name="float" type="floating"><parent link="world"/><child link="base"/>'
            '</joint></robot>')
    floating = ARM.read_text().replace("</robot>", free)
    tree = _read(floating)
    assert tree.nq == 11 and tree.bodies[0].name == "base"  # the floating joint is the free joint
    with pytest.raises(ValueError, match=r"this robot's root already floats: drop floating_base"):
        _read(floating, floating_base=True)
    mesh = ARM.read_text().replace('<sphere radius="0.03"/>', '<mesh filename="package://arm/tip.stl"/>')
    with pytest.raises(NotImplementedError, match=r"<link name=\"slider\"> <collision> 0: a <mesh> collision"):
        _read(mesh, contact=lg.PenaltyContact(2e4, 1e3, 1e3, 0.9))
    assert _read(mesh).nv == 4  # without contact the mesh is never opened


def test_a_floating_quadruped_on_the_ground_differentiates_as_central_differences():
    """The example's Solo12 (floating base, a sphere given by hand on each foot pressing the ground, position
    actuators from ``motors=``) on its feet: the gradient of a short rollout's final trunk height with respect to the
    actuators' targets, forward mode, equals central differences."""
    feet = {f"{leg}_FOOT": [(0.0, 0.0, 0.0, 0.016)] for leg in ("FL", "FR", "HL", "HR")}
    tree = from_urdf(SOLO12, floating_base=True, motors=lambda k: lg.AffineActuator.position(k, 5.0, 0.1),
                     contact=lg.PenaltyContact(5e3, 50.0, 250.0, 0.9), contact_points=feet)
    assert [len(b.contacts) for b in tree.bodies] == [0] + [0, 0, 1] * 4 and tree.m == 12
    q0 = np.array(tree.neutral(), float)
    q0[7:] = [0, 0.8, -1.6] * 2 + [0, -0.8, 1.6] * 2
    q0[2] += 0.016 - 0.002 - np.min(np.asarray(contact_point_positions(tree, jnp.asarray(q0)))[:, 2])  # 2 mm in
    targets = jnp.asarray(np.tile(q0[7:], (4, 1)))

    @jax.jit
    def height(targets):
        traj = lg.simulate(tree, jnp.asarray(q0), jnp.zeros(tree.nv), targets, 0.005, lg.SemiImplicitEuler(), 5)
        return traj.q[-1, 2]

    e = np.zeros(targets.shape)
    e[0, 1], e[1, 5], e[2, 10] = 1.0, -0.5, 0.7  # thighs and a calf
    _, slope = jax.jvp(height, (targets,), (jnp.asarray(e),))
    fd = (height(targets + 1e-6 * e) - height(targets - 1e-6 * e)) / 2e-6
    assert abs(float(fd)) > 1e-4  # the targets move the trunk
    assert abs(float(slope) - float(fd)) <= 1e-6 * max(1e-3, abs(float(fd))), (float(slope), float(fd))


def test_points_given_by_hand_and_an_actuator_per_joint():
    """``contact_points`` places a link's points in its frame (through the fixed joint that merged it into its body)
    in place of any collision geometry; ``motors=`` a function puts its actuator on every hinge and slide; bad ones
    are refused by name."""
    contact = lg.PenaltyContact(2e4, 1e3, 1e3, 0.9)
    tree = _read(contact=contact, contact_points={"flange": [(0.0, 0.0, 0.1, 0.01)]},
                 motors=lambda k: lg.AffineActuator.position(k, 50.0, 1.0))
    assert [len(b.contacts) for b in tree.bodies] == [1, 0, 0, 0]  # the hand-given point only: no box, no sphere
    # the flange hangs from the upper arm at xyz (0, 0.02, 0.4), rpy (0.4, 0, 0): the point turned about x, moved
    assert np.allclose(tree.bodies[0].contacts[0], (0.0, 0.02 - 0.1 * np.sin(0.4), 0.4 + 0.1 * np.cos(0.4), 0.01),
                       rtol=0, atol=1e-15)
    both = _read(contact=contact, contact_links=["slider"], contact_points={"flange": [(0.0, 0.0, 0.1, 0.01)]})
    assert [len(b.contacts) for b in both.bodies] == [1, 0, 1, 0]  # and the slider's sphere
    assert all(isinstance(mo, lg.AffineActuator) for mo in tree.motors)
    assert [mo.joint for mo in tree.motors] == [0, 1, 2, 3] and float(tree.motors[2].gain) == 50.0
    with pytest.raises(ValueError, match=r"from_urdf: the URDF text: contact_points names links that do not exist: "
                                         r"\['heel'\]"):
        _read(ARM.read_text(), contact=contact, contact_points={"heel": [(0, 0, 0, 0.01)]})
    with pytest.raises(ValueError, match=r"from_urdf.contact_points\['tool'\]\[0\] must be finite with radius >= 0"):
        _read(contact=contact, contact_points={"tool": [(0, 0, 0, -0.01)]})
    with pytest.raises(TypeError, match=r"from_urdf: motors must be True, False or a function"):
        _read(motors="position")
