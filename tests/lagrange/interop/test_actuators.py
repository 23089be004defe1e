"""MuJoCo's ``<position>``, ``<velocity>`` and affine ``<general>`` actuators, read as
:class:`lagrange.AffineActuator` s, equal MuJoCo: ``qfrc_actuator`` and ``qacc`` at random states with the controls
and the forces clamped (``ctrlrange``, ``forcerange``), through ``to_mjcf`` and back, and in a rollout whose gradient
equals central differences. What a tree cannot carry is refused by name."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.dynamics import backend
from lagrange.interop.mjcf import from_mjcf, to_mjcf
from lagrange.rbda.backend import General
from tests.helpers import mujoco_forward, rel

ARM = """<mujoco><option timestep="0.002"><flag contact="disable"/></option><worldbody>
<body pos="0 0 1"><joint name="j0" type="hinge" axis="0 1 0" damping="0.1"/>
  <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
 <body pos="0.3 0 0"><joint name="j1" type="hinge" axis="1 0 1"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
  <body pos="0 0 -0.3"><joint name="j2" type="slide" axis="0 0 1"/><geom type="sphere" size="0.05"/>
   <body><joint name="j3" type="ball"/><geom type="box" size=".05 .02 .03" pos="0.05 0 0"/></body></body></body></body>
</worldbody><actuator>
<position joint="j0" kp="30" kv="2" gear="1.5" ctrlrange="-1 1" ctrllimited="true"/>
<velocity joint="j1" kv="4" forcerange="-0.5 0.7" forcelimited="true"/>
<general joint="j2" gainprm="3" biasprm="0.2 -5 -0.3" biastype="affine" gear="2" forcerange="-3 3"/>
</actuator></mujoco>"""
EXACT = 1e-12


def _states(model, n, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q = rng.uniform(-1, 1, model.nq)
        q[-4:] /= np.linalg.norm(q[-4:])
        yield q, rng.uniform(-2, 2, model.nv), rng.uniform(-2, 2, model.nu)


def test_affine_actuators_equal_mujoco_and_survive_the_round_trip():
    import mujoco

    model = mujoco.MjModel.from_xml_string(ARM)
    tree = from_mjcf(ARM)
    assert [type(mo).__name__ for mo in tree.motors] == ["AffineActuator"] * 3
    np.testing.assert_array_equal(tree.motors[0].bias, [0.0, -30.0, -2.0])  # <position kp kv>
    assert [j.name for j in tree.joints] == ["j0", "j1", "j2", "j3"] and tree.joint_index("j2") == 2
    again = mujoco.MjModel.from_xml_string(to_mjcf(tree))
    b = backend(tree)
    terms = jax.jit(lambda q, qd, u: (b.actuation(u, q, qd), lg.forward_dynamics(tree, q, qd, u)))
    clamped = set()
    for q, qd, u in _states(model, 6):
        data, _ = mujoco_forward(model, q, qd, u)
        act, qdd = terms(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u))
        assert rel(act, data.qfrc_actuator) <= EXACT and rel(qdd, data.qacc) <= EXACT
        back, _ = mujoco_forward(again, q, qd, u)
        assert rel(back.qfrc_actuator, data.qfrc_actuator) <= EXACT and rel(back.qacc, data.qacc) <= EXACT
        clamped |= {k for k, ends in ((1, (-0.5, 0.7)), (2, (-3.0, 3.0))) if data.actuator_force[k] in ends}
    assert clamped == {1, 2}  # both force ranges were met


def test_a_rollout_with_servos_and_its_gradient():
    tree = from_mjcf(ARM)
    q0 = jnp.asarray(tree.neutral()) + 0.1
    q0 = q0.at[-4:].set(q0[-4:] / jnp.linalg.norm(q0[-4:]))
    us = jnp.asarray(np.random.default_rng(1).uniform(-1, 1, (10, 3)))

    @functools.partial(jax.jit, static_argnums=(1, 2))
    def final(us, solver, substeps):
        return lg.simulate(tree, q0, jnp.zeros(tree.nv), us, 0.004, solver, substeps).q[-1, :3].sum()

    held, sie = lg.SemiImplicitEuler(hold_mass_matrix=True), lg.SemiImplicitEuler()
    # the held mass matrix path adds each substep's own actuator forces: one substep is plain semi-implicit Euler
    assert abs(final(us, held, 1) - final(us, sie, 1)) <= 1e-13
    e = np.zeros(us.shape)
    e[4, 0] = e[7, 2] = 1.0
    _, slope = jax.jvp(lambda us: final(us, sie, 1), (us,), (jnp.asarray(e),))
    fd = (final(us + 1e-6 * e, sie, 1) - final(us - 1e-6 * e, sie, 1)) / 2e-6
    assert abs(float(slope) - float(fd)) <= 1e-7 * max(1.0, abs(float(fd)))


def test_a_planar_model_with_a_position_actuator_runs_on_the_general_algorithms():
    xml = ("<mujoco><worldbody><body><joint name='h' type='hinge' axis='0 1 0'/>"
           "<geom type='capsule' fromto='0 0 0 0 0 -1' size='0.05'/></body></worldbody>"
           "<actuator><position joint='h' kp='10'/></actuator></mujoco>")
    tree = from_mjcf(xml)
    assert tree.planar and isinstance(backend(tree), General)  # the planar backends carry motors only
    with pytest.raises(NotImplementedError, match=r"is not a motor: its bias makes it a servo"), \
            pytest.warns(DeprecationWarning, match="tree= is deprecated"):
        from_mjcf(xml, tree=False)
    by_hand = lg.Tree(tree.bodies, tree.gravity, motors=[lg.AffineActuator.position(0, kp=10.0)])
    q, qd, u = jnp.asarray([0.3]), jnp.asarray([0.2]), jnp.asarray([0.1])
    assert float(lg.forward_dynamics(by_hand, q, qd, u)[0]) == float(lg.forward_dynamics(tree, q, qd, u)[0])


@pytest.mark.parametrize("actuator, message", [
    ("<intvelocity joint='h' kp='10' actrange='-1 1'/>", r"neither a motor nor an affine actuator on a joint"),
    ("<general joint='h' gaintype='affine' gainprm='1 2'/>", r"neither a motor nor an affine actuator on a joint"),
])
def test_what_a_tree_cannot_carry_is_refused(actuator, message):
    xml = ("<mujoco><worldbody><body><joint name='h' type='hinge' axis='0 1 0'/><geom size='0.1'/>"
           f"<body><joint type='hinge' axis='1 0 0'/><geom size='0.1'/></body></body></worldbody>"
           f"<actuator>{actuator}</actuator></mujoco>")
    with pytest.raises(NotImplementedError, match=message):
        from_mjcf(xml)
    frc = xml.replace("<joint name='h' type='hinge' axis='0 1 0'/>",
                      "<joint name='h' type='hinge' axis='0 1 0' actuatorfrcrange='-1 1'/>")
    with pytest.raises(NotImplementedError, match=r"joint 'h'.* has an actuatorfrcrange"):
        from_mjcf(frc.replace(actuator, "<motor joint='h'/>"))
