"""``from_mjcf``: the planar models that ship with dm_control, Gymnasium and Brax, read through MuJoCo's compiler,
against MuJoCo itself (``q = qpos``, ``qd = qvel``, ``u = ctrl``): the mass matrix (``mj_fullM``), the bias forces
(``qfrc_bias - qfrc_passive``) and ``qacc`` at random in-range states to 1e-10 relative, and 30-step rollouts with the
model's own integrator (``solver_of``) to 1e-9; the ten legged and branched models (hoppers, cheetahs, walkers, the
reacher and its target) in free flight (contacts and limits disabled on both sides, ``mjDSBL_CONSTRAINT``) at random
states, far from rest included; a hand-written model with every feature the import maps (multi-joint
bodies, jointless bodies, rotated frames, ``ref``, armature, degrees, ``fromto``, an off-line centre of mass, in-plane
gravity); the round trip through ``to_mjcf``; and the refusals, each naming the feature and the element."""

from __future__ import annotations

import importlib.util
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop.mjcf import from_mjcf, mujoco_rollout, solver_of, to_mjcf
from lagrange.model.tree import Tree
from lagrange.planar.lower import lower as planar
from tests.helpers import mujoco_terms, rel

EXACT = 1e-10
ROLLOUT = 1e-9


def _package_dir(name: str) -> pathlib.Path:
    return pathlib.Path(importlib.util.find_spec(name).submodule_search_locations[0])


DMC = _package_dir("dm_control") / "suite"
GYM = _package_dir("gymnasium") / "envs" / "mujoco" / "assets"
BRAX = _package_dir("brax") / "envs" / "assets"

# the planar chains of the three suites
MODELS = {
    "dm_control/acrobot": DMC / "acrobot.xml",
    "dm_control/cartpole": DMC / "cartpole.xml",
    "dm_control/pendulum": DMC / "pendulum.xml",
    "dm_control/reacher": DMC / "reacher.xml",
    "gymnasium/inverted_pendulum": GYM / "inverted_pendulum.xml",
    "gymnasium/inverted_double_pendulum": GYM / "inverted_double_pendulum.xml",
    "brax/inverted_pendulum": BRAX / "inverted_pendulum.xml",
    "brax/inverted_double_pendulum": BRAX / "inverted_double_pendulum.xml",
}

# the planar trees with a floating base, and the reacher with its target (a second tree): their geoms touch the floor
# (and limits bound their joints), so they load with contact="ignore", limits="ignore" and are compared in free flight
TREES = {
    "gymnasium/hopper": GYM / "hopper.xml",
    "gymnasium/half_cheetah": GYM / "half_cheetah.xml",
    "gymnasium/walker2d": GYM / "walker2d.xml",
    "gymnasium/reacher": GYM / "reacher.xml",
    "dm_control/hopper": DMC / "hopper.xml",
    "dm_control/cheetah": DMC / "cheetah.xml",
    "dm_control/walker": DMC / "walker.xml",
    "brax/hopper": BRAX / "hopper.xml",
    "brax/half_cheetah": BRAX / "half_cheetah.xml",
    "brax/walker2d": BRAX / "walker2d.xml",
}

# a model with every feature the import maps onto a chain: a slide with ref and armature along a tilted axis, a
# body turned about the plane's normal (euler, degrees), a hinge with ref, a centre of mass off the link line, a body
# with two joints, a jointless body merged into its parent, gravity with an in-plane tilt and a normal part,
# inertias from geoms (fromto), a limited control range on one motor, damping everywhere
KITCHEN_SINK = """
<mujoco model="kitchen_sink">
  <compiler angle="degree" inertiafromgeom="true"/>
  <option timestep="0.005" integrator="RK4" gravity="0.7 -0.4 -9.3">
    <flag contact="disable"/>
  </option>
  <default><joint damping="0.03"/><geom size="0.04"/></default>
  <worldbody>
    <body name="cart" pos="0.3 0 1.2" euler="0 20 0">
      <joint name="slide" type="slide" axis="1 0 0.2" ref="0.15" armature="0.02"/>
      <geom type="box" size="0.2 0.1 0.05" mass="2"/>
      <body name="arm" pos="0.1 0 0" euler="0 -35 0">
        <joint name="shoulder" type="hinge" axis="0 1 0" ref="12"/>
        <geom type="capsule" fromto="0 0 0 0.1 0 0.7" mass="0.8"/>
        <geom type="sphere" pos="0.15 0 0.35" size="0.06" mass="0.3"/>
        <body name="forearm" pos="0.1 0 0.7" euler="0 50 0">
          <joint name="elbow_slide" type="slide" axis="0 0 1" armature="0.01"/>
          <joint name="elbow" type="hinge" axis="0 1 0" pos="0 0 0.05"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.5" mass="0.5"/>
          <body name="hand" pos="0 0.02 0.5" euler="0 10 0">
            <geom type="box" size="0.05 0.05 0.08" pos="0.03 0 0.02" mass="0.2"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="slide" gear="5" ctrllimited="true" ctrlrange="-1 2"/>
    <motor joint="shoulder" gear="3"/>
    <motor joint="elbow" gear="1.5"/>
  </actuator>
</mujoco>
"""


def _load(source, **kw):
    if isinstance(source, str):
        model = mujoco.MjModel.from_xml_string(source)
    else:
        model = mujoco.MjModel.from_xml_path(str(source))
    return model, from_mjcf(source, **kw)


def _random_states(model, rng, k=6, scale=1.0):
    """States inside every joint's range (the limits are loaded as ``limits="ignore"``), velocities scaled by
    ``scale`` and positions by ``0.9 scale`` of the range."""
    lo = np.where(model.jnt_limited, model.jnt_range[:, 0], -np.pi)
    hi = np.where(model.jnt_limited, model.jnt_range[:, 1], np.pi)
    q = rng.uniform(0.9 * min(scale, 1.0) * lo, 0.9 * min(scale, 1.0) * hi, (k, model.nq))
    qd = scale * rng.uniform(-2, 2, (k, model.nv))
    u = rng.uniform(-2, 2, (k, model.nu))  # beyond the control ranges too: both clamp
    return q, qd, u


def _ours(chain, q, qd, u):
    u = jnp.asarray(u) if chain.m else None
    q, qd = jnp.asarray(q), jnp.asarray(qd)
    return lg.mass_matrix(chain, q), lg.bias_forces(chain, q, qd), lg.forward_dynamics(chain, q, qd, u)


def _check_terms(model, chain, seed=0, scales=(1.0,)):
    """M, bias and qacc at random states (:func:`_random_states`, one batch per scale), all in one compiled call."""
    rng = np.random.default_rng(seed)
    q, qd, u = (np.concatenate(x) for x in zip(*(_random_states(model, rng, scale=scale) for scale in scales)))
    ours = eqx.filter_jit(jax.vmap(_ours, in_axes=(None, 0, 0, 0)))(chain, jnp.asarray(q), jnp.asarray(qd),
                                                                      jnp.asarray(u))
    for k in range(len(q)):
        for name, a, b in zip(("M", "bias", "qacc"), (o[k] for o in ours), mujoco_terms(model, q[k], qd[k], u[k])):
            assert rel(a, b) <= EXACT, f"{name} at state {k}: {rel(a, b):.1e}"


def _check_rollout(model, chain, seed=1, steps=30):
    """``steps`` of ``mj_step`` against ``lagrange.simulate`` with ``solver_of``'s integrator, from an in-range state
    under small controls; MuJoCo must meet no constraint on the way (``nefc == 0``), or the comparison would not be
    of the same system."""
    rng = np.random.default_rng(seed)
    q0, qd0, _ = _random_states(model, rng, k=1, scale=0.05)
    us = rng.uniform(-0.3, 0.3, (steps, model.nu))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q0[0], qd0[0]
    qs, qds = [], []
    for k in range(steps):
        data.ctrl[:] = us[k]
        mujoco.mj_step(model, data)
        assert data.nefc == 0, "the rollout met a constraint; pick a calmer state"
        qs.append(np.array(data.qpos))
        qds.append(np.array(data.qvel))
    solver, dt = solver_of(model)
    traj = lg.simulate(chain, jnp.asarray(q0[0]), jnp.asarray(qd0[0]), jnp.asarray(us) if chain.m else None, dt,
                       solver, steps=steps)
    assert rel(np.asarray(traj.q)[1:], np.array(qs)) <= ROLLOUT
    assert rel(np.asarray(traj.qd)[1:], np.array(qds)) <= ROLLOUT


@pytest.mark.parametrize("name", list(MODELS))
def test_suite_models_match_mujoco(name):
    model, chain = _load(MODELS[name], limits="ignore")
    assert chain.nv == model.nq == model.nv and chain.m == model.nu
    _check_terms(model, chain)
    _check_rollout(model, chain)


def _free_flight(path):
    """The model compiled with every constraint disabled (no contact, no limit), and the chain read from it as a user
    reads it: ``limits="ignore", contact="ignore"``."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return model, from_mjcf(path, limits="ignore", contact="ignore")


@pytest.mark.parametrize("name", list(TREES))
def test_trees_match_mujoco_in_free_flight(name):
    """M, bias and qacc to 1e-10 at random states (joints over 0.9 of their range, the root anywhere within pi) and
    at states five times as far and as fast; 30-step rollouts of the model's own integrator to 1e-9."""
    model, chain = _free_flight(TREES[name])
    assert chain.nv == model.nq == model.nv and chain.m == model.nu
    assert not planar(chain).serial or name.endswith("hopper")  # the cheetahs, walkers and the reacher branch
    _check_terms(model, chain, scales=(1.0, 5.0))
    _check_rollout(model, chain)


def test_trees_are_refused_by_default_naming_contact():
    """By default a model whose geoms can touch the floor is refused, naming the geoms and the way out."""
    for name in ("gymnasium/hopper", "dm_control/cheetah", "brax/walker2d"):
        with pytest.raises(NotImplementedError,
                           match="geoms can touch \\(geom '(floor|ground)' and geom .*contact=\"ignore\""):
            from_mjcf(TREES[name], limits="ignore")
    with pytest.raises(ValueError, match=r"contact must be one of \('raise', 'ignore'\)"):
        from_mjcf(TREES["gymnasium/hopper"], contact="penalty")


def test_tree_structure_is_mujoco_s():
    """The half-cheetah branches at the torso: rootx -> rootz -> rooty, then back and front legs of three links each;
    its springs are MuJoCo's; the hopper's root hinge turns the other way round to its legs (sense -1 on the root);
    the reacher's target hangs from the world beside the arm."""
    _, cheetah = _free_flight(TREES["gymnasium/half_cheetah"])
    lowered = planar(cheetah)
    assert cheetah.parents == (-1, 0, 1, 2, 0, 4, 5) and lowered.parents == (-1, 0, 1, 2, 3, 4, 2, 6, 7)
    assert lowered.joints[:3] == ("prismatic",) * 2 + ("revolute",)
    assert lowered.sprung == tuple(range(3, 9)) and np.allclose(lowered.stiffness[3:], [240, 180, 120, 180, 120, 60])
    _, hopper = _free_flight(TREES["gymnasium/hopper"])
    assert planar(hopper).senses == (1, 1, -1, 1, 1, 1)  # the plane's normal is +y: rooty turns about -y
    _, reacher = _free_flight(TREES["gymnasium/reacher"])
    assert reacher.parents == (-1, 0, 1, -1)  # body0, body1, the fingertip welded to it, the target
    assert planar(reacher).parents == (-1, 0, -1, 2)  # its links: the arm's two hinges, the target's two slides


@pytest.mark.parametrize("name", ["gymnasium/half_cheetah", "gymnasium/reacher", "gymnasium/hopper"])
def test_trees_round_trip_through_to_mjcf(name):
    model, chain = _free_flight(TREES[name])
    again = mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=float(model.opt.timestep)))
    q, qd, u = _random_states(model, np.random.default_rng(3))
    for k in range(len(q)):
        for a, b in zip(mujoco_terms(again, q[k], qd[k], u[k]), mujoco_terms(model, q[k], qd[k], u[k])):
            assert rel(a, b) <= EXACT
    same = from_mjcf(to_mjcf(chain))
    lowered, lowered_same = planar(chain), planar(same)
    assert same.parents == chain.parents
    assert lowered_same.senses == lowered.senses and lowered_same.sprung == lowered.sprung
    both = eqx.filter_jit(lambda a, b, q: (lg.mass_matrix(a, q), lg.mass_matrix(b, q)))  # one compiled program
    assert rel(*both(same, chain, jnp.asarray(q))) <= EXACT


def test_kitchen_sink_matches_mujoco():
    model, chain = _load(KITCHEN_SINK)
    lowered = planar(chain)
    assert lowered.joints == ("prismatic", "revolute", "prismatic", "revolute")
    assert lowered.com_normal is not None and any(o != 0 for o in lowered.offsets)
    assert lowered.armature is not None and lowered.control_ranges == ((-1.0, 2.0), None, None)
    assert np.isclose(float(lowered.gravity), np.hypot(0.7, 9.3))  # the plane is x-z: the y part does no work
    assert chain.actuated == (0, 1, 3) and np.allclose(chain.gear, [5.0, 3.0, 1.5])
    _check_terms(model, chain)
    _check_rollout(model, chain)


def test_sources_and_solvers():
    """A path, an XML string and a compiled model give the same chain; the integrators map as documented."""
    path = MODELS["dm_control/acrobot"]
    model = mujoco.MjModel.from_xml_path(str(path))
    chains = [from_mjcf(path), from_mjcf(str(path)), from_mjcf(model), from_mjcf(path.read_text().replace(
        'file="./common', f'file="{DMC}/common'))]
    for c in chains[1:]:
        assert jax.tree_util.tree_all(jax.tree_util.tree_map(lambda a, b: np.array_equal(a, b), chains[0], c))
    assert isinstance(solver_of(model)[0], lg.RK4) and solver_of(model)[1] == 0.01
    assert isinstance(solver_of(MODELS["dm_control/pendulum"])[0], lg.SemiImplicitEuler)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    with pytest.raises(NotImplementedError, match="IMPLICITFAST.*Euler"):
        solver_of(model)
    with pytest.raises(FileNotFoundError, match="no MJCF file"):
        from_mjcf("/no/such/model.xml")
    with pytest.raises(TypeError, match="source must be"):
        from_mjcf(3.0)
    with pytest.raises(ValueError, match=r"limits must be one of \('raise', 'ignore'\)"):
        from_mjcf(path, limits="clip")


@pytest.mark.parametrize("name", list(MODELS))
def test_round_trip_through_to_mjcf(name):
    """``to_mjcf(from_mjcf(x))`` is the same system as ``x``: equal ``qacc`` (and ``M``, bias) at random states."""
    model, chain = _load(MODELS[name], limits="ignore")
    again = mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=float(model.opt.timestep)))
    q, qd, u = _random_states(model, np.random.default_rng(3))
    for k in range(len(q)):
        for a, b in zip(mujoco_terms(again, q[k], qd[k], u[k]), mujoco_terms(model, q[k], qd[k], u[k])):
            assert rel(a, b) <= EXACT
    again = from_mjcf(to_mjcf(chain))
    assert again.parents == chain.parents and [type(j) for j in again.joints] == [type(j) for j in chain.joints]
    _check_terms(model, again)  # read back from what to_mjcf wrote, it is still MuJoCo's model


def _chain_xml(joints: str, body_extra: str = "", model_extra: str = "", option: str = "", child: str = "",
               world: str = "") -> str:
    return f"""<mujoco>
  <option{option}/>
  <worldbody>
    <body name="a">
      {joints}
      <geom name="ga" type="capsule" fromto="0 0 0 0 0 -1" size="0.05" contype="0" conaffinity="0"/>
      <body name="b" pos="0 0 -1">
        <joint name="j2" type="hinge" axis="0 1 0"/>
        <geom name="gb" type="capsule" fromto="0 0 0 0 0 -1" size="0.05" contype="0" conaffinity="0"/>
        {body_extra}
      </body>
      {child}
    </body>
    {world}
  </worldbody>
  {model_extra}
</mujoco>"""


HINGE = '<joint name="j1" type="hinge" axis="0 1 0"/>'
GC = '<geom name="gc" type="sphere" size="0.1" pos="0 0 -1"/>'  # on the tip of link b, colliding by default
GW = '<geom name="gw" type="plane" size="5 5 1" pos="0 0 -3"/>'  # a floor

SPATIAL = [  # what the planar backend cannot carry (3-D joints, affine or force-limited actuators): a tree on the
    # general algorithms, refused with the deprecated tree=False
    ("ball joint", _chain_xml('<joint name="j1" type="ball"/>'), "joint 'j1' is a ball joint"),
    ("free joint", _chain_xml('<freejoint name="j1"/>'), "joint 'j1' is a free joint"),
    ("tilted hinge", _chain_xml('<joint name="j1" type="hinge" axis="1 1 0"/>'), "not parallel.*leaves the plane"),
    ("slide out of plane", _chain_xml('<joint name="j1" type="slide" axis="0 1 0"/>'),
     "joint 'j1' slides along .* out of the plane"),
    ("position servo", _chain_xml(HINGE, model_extra='<actuator><position name="p" joint="j1" kp="10"/></actuator>'),
     "actuator 'p' is not a motor: its bias makes it a servo"),
    ("force limit", _chain_xml(HINGE,
                               model_extra='<actuator><motor name="m" joint="j1" forcerange="-1 1"/></actuator>'),
     "actuator 'm' is force-limited"),
    ("motors out of joint order", _chain_xml(HINGE, model_extra='<actuator><motor joint="j2"/><motor joint="j1"/>'
                                                                '</actuator>'),
     r"actuators drive joints \[1, 0\], out of joint order"),
    ("slides in three directions", _chain_xml('<joint name="j1" type="slide" axis="1 0 0"/><joint name="j3" '
                                              'type="slide" axis="0 1 0"/><joint name="j4" type="slide" axis="0 0 1"/>'
                                              ).replace('<joint name="j2" type="hinge" axis="0 1 0"/>',
                                                        '<joint name="j2" type="slide" axis="1 0 0"/>'),
     "its slides move along three independent directions"),
]


@pytest.mark.parametrize("what, xml, match", SPATIAL, ids=[r[0] for r in SPATIAL])
def test_what_the_planar_backend_cannot_carry_loads_and_the_deprecated_tree_false_refuses_it(what, xml, match):
    tree = from_mjcf(xml)
    assert isinstance(tree, Tree) and planar(tree) is None
    with pytest.raises(NotImplementedError, match=match), pytest.warns(DeprecationWarning, match="tree= is deprecated"):
        from_mjcf(xml, tree=False)


def test_a_planar_model_is_lowered_and_the_deprecated_tree_argument_changes_nothing():
    tree = from_mjcf(MODELS["dm_control/acrobot"])
    assert tree.planar and planar(tree) is not None
    for flag in (True, False):
        with pytest.warns(DeprecationWarning, match="tree= is deprecated"):
            same = from_mjcf(MODELS["dm_control/acrobot"], tree=flag)
        assert jax.tree_util.tree_structure(same) == jax.tree_util.tree_structure(tree)


REFUSALS = [
    ("contact", _chain_xml(HINGE, body_extra=GC, world=GW), NotImplementedError,
     "geom 'gw' and geom 'gc'.*contact=\"ignore\".*contact=\"disable\""),
    ("contact pair", _chain_xml(HINGE, model_extra='<contact><pair geom1="ga" geom2="gb"/></contact>'),
     NotImplementedError, "explicit contact pair"),
    ("friction loss", _chain_xml('<joint name="j1" type="hinge" axis="0 1 0" frictionloss="0.1"/>'),
     NotImplementedError, "joint 'j1' has frictionloss"),
    ("tendon", _chain_xml(HINGE, model_extra='<tendon><fixed name="t" stiffness="3"><joint joint="j1" coef="1"/>'
                                             '</fixed></tendon>'),
     NotImplementedError, "tendon 't' carries force"),
    ("equality", _chain_xml(HINGE, model_extra='<equality><joint name="eq" joint1="j1" joint2="j2"/></equality>'),
     NotImplementedError, "equality 'eq'"),
    ("negative gear", _chain_xml(HINGE, model_extra='<actuator><motor name="m" joint="j1" gear="-2"/></actuator>'),
     NotImplementedError, "actuator 'm' has gear \\* gain = -2"),
    ("two motors", _chain_xml(HINGE, model_extra='<actuator><motor joint="j1"/><motor joint="j1"/></actuator>'),
     NotImplementedError, "joint 'j1' has more than one actuator"),
    ("limit", _chain_xml('<joint name="j1" type="hinge" axis="0 1 0" range="-1 1" limited="true"/>'), ValueError,
     "joint 'j1' is limited.*limits=\"ignore\""),
    ("fluid", _chain_xml(HINGE, option=' density="1.2"'), NotImplementedError, "fluid forces"),
    ("no joint", "<mujoco><worldbody><geom size='1'/></worldbody></mujoco>", ValueError, "no joint"),
]


@pytest.mark.parametrize("what, xml, error, match", REFUSALS, ids=[r[0] for r in REFUSALS])
def test_refusals_name_the_feature_and_the_element(what, xml, error, match):
    with pytest.raises(error, match=match):
        from_mjcf(xml)


def test_actuators_out_of_joint_order_and_a_tendon_without_force_load_as_mujoco_s():
    """``u = ctrl`` in the actuators' order, whatever the joints' order; a tendon that carries no force changes
    nothing."""
    xml = _chain_xml(HINGE, model_extra='<tendon><fixed name="t"><joint joint="j1" coef="1"/></fixed></tendon>'
                                        '<actuator><motor name="m2" joint="j2" gear="2"/><motor name="m1" joint="j1"/>'
                                        '</actuator>')
    model, tree = _load(xml)
    assert [mo.joint for mo in tree.motors] == [1, 0] and planar(tree) is None  # the general algorithms carry it
    _check_terms(model, tree)


def test_mujoco_rollout_steps_mujoco_and_reports_constraints():
    model = mujoco.MjModel.from_xml_path(str(MODELS["dm_control/cartpole"]))
    data = mujoco.MjData(model)
    q0, qd0, us = np.array([0.1, 0.2]), np.array([0.0, 0.5]), np.full((20, 1), 0.3)
    data.qpos[:], data.qvel[:] = q0, qd0
    expected = [np.r_[q0, qd0]]
    for u in us:
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
        expected.append(np.r_[data.qpos, data.qvel])
    states, met = mujoco_rollout(model, q0, qd0, us)
    assert states.shape == (21, 4) and not met and np.array_equal(states, np.array(expected))
    _, met = mujoco_rollout(model, np.array([1.75, 0.0]), np.array([3.0, 0.0]), np.zeros((10, 1)))
    assert met  # the slider runs into its limit at 1.8 m


def test_what_disabling_a_constraint_allows():
    """With contacts or all constraints disabled the colliding geoms and the limit are no obstacle: MuJoCo applies
    neither, so the chain is exact."""
    contact = _chain_xml(HINGE, body_extra=GC, world=GW)
    for flag in ('contact="disable"', 'constraint="disable"'):
        xml = contact.replace("<option/>", f"<option><flag {flag}/></option>")
        _check_terms(mujoco.MjModel.from_xml_string(xml), from_mjcf(xml))
    limited = _chain_xml('<joint name="j1" type="hinge" axis="0 1 0" range="-1 1" limited="true"/>')
    from_mjcf(limited.replace("<option/>", '<option><flag limit="disable"/></option>'))
