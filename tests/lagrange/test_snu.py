"""DFlex's SNU humanoid (``lagrange.tasks.SNUHumanoid``, on ``lagrange.tasks.snu_tree.snu_tree``) against its
reference: the skeleton's masses, box inertias, joint frames and start height against the facts read off DFlex's loader
(``shared/snu-humanoid.md``'s table, DFlex's numbers); the 152 muscles kept and their order; the skeleton and all its
muscles against MuJoCo (spatial tendons through sites); DFlex's ball spring; the observation, a hand-computed reward,
the early end and the reset's noise."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop.mjcf import to_mjcf
from lagrange.model.joints import DFlexBall
from lagrange.tasks import SNUHumanoid, TaskState
from lagrange.tasks.snu_tree import BODIES, snu_tree
from tests.helpers import rel

# (body, parent, X_pj [m], kg, DFlex inertia diagonal [kg m^2], box quaternion (x, y, z, w)): the reference's table
TABLE = (
    ("Pelvis", -1, (0, 0, 0), 15, (0.047357, 0.075167, 0.080663), (0, 0, 0, 1)),
    ("FemurR", 0, (-0.0903, -0.0472, 0.0192), 7, (0.105522, 0.020812, 0.103568),
     (0.99852, -0.00871, -0.05303, 0.00859)),
    ("TibiaR", 1, (-0.0092, -0.395, 0.0013), 3, (0.046379, 0.006782, 0.046413), (0.9989, 0.01744, -0.00075, -0.04362)),
    ("TalusR", 2, (0.0195, -0.4611, -0.0316), 0.6, (0.001297, 0.001516, 0.000392),
     (0.99438, 0.01144, 0.10439, -0.01363)),
    ("FootThumbR", 3, (0.0019, -0.0575, 0.1111), 0.2, (6.2e-5, 8.0e-5, 3.8e-5), (0.99613, -0.00567, 0.08724, -0.00936)),
    ("FootPinkyR", 3, (-0.0427, -0.0634, 0.0913), 0.2, (5.0e-5, 7.6e-5, 3.5e-5), (0.9849, 0.00531, 0.17291, -0.00627)),
    ("FemurL", 0, (0.0903, -0.0472, 0.0192), 7, (0.105522, 0.020812, 0.103568), (-0.00859, -0.05303, 0.00871, 0.99852)),
    ("TibiaL", 6, (0.0092, -0.395, 0.0013), 3, (0.046379, 0.006782, 0.046413), (0.04362, -0.00075, -0.01744, 0.9989)),
    ("TalusL", 7, (-0.0195, -0.4611, -0.0316), 0.6, (0.001297, 0.001516, 0.000392),
     (0.01363, 0.10439, -0.01144, 0.99438)),
    ("FootThumbL", 8, (0.0415, -0.066, 0.0913), 0.2, (5.7e-5, 8.0e-5, 3.5e-5), (0.00627, 0.17291, -0.00531, 0.9849)),
    ("FootPinkyL", 8, (-0.0044, -0.0658, 0.1095), 0.2, (5.4e-5, 7.6e-5, 3.8e-5), (0.00936, 0.08724, 0.00567, 0.99613)),
)


@pytest.fixture(scope="module")
def tree():
    return snu_tree()


def test_the_skeleton_is_dflex_s(tree):
    """Masses, DFlex's elementwise-turned box inertias, the joint frames and kinds, the per-joint constants and the
    start (COM at 0.742 m, the lowest box corner at 0.0314 m), as the reference's table gives them (its digits)."""
    from lagrange.tasks.snu_tree import dflex_quat
    from lagrange.tasks.snu_tree import _nodes, ASSETS

    nodes = _nodes(ASSETS / "human.xml")
    assert (tree.nq, tree.nv, tree.m, len(tree.bodies)) == (29, 24, 152, 11)
    assert [b.name for b in tree.bodies] == list(BODIES) and math.isclose(float(jnp.sum(tree.mass)), 37.0)
    for b, (name, parent, xpj, kg, inertia, quat) in zip(tree.bodies, TABLE):
        assert b.parent == parent and float(b.mass) == kg
        if parent >= 0:
            np.testing.assert_allclose(b.pos, xpj, atol=1e-12)
        J = np.asarray(b.inertia)
        assert np.array_equal(J, np.diag(np.diag(J)))  # DFlex drops the products of inertia
        np.testing.assert_allclose(np.diag(J), inertia, rtol=6e-3, atol=6e-7)  # the table's digits
        w, x, y, z = dflex_quat(nodes[name]["body_R"])
        np.testing.assert_allclose((x, y, z, w), quat, atol=6e-5)
    kinds = [type(j).__name__ for j in tree.joints]
    assert kinds == ["Free"] + ["DFlexBall", "Hinge", "DFlexBall", "Hinge", "Hinge"] * 2
    femur, knee, toe = tree.joints[1], tree.joints[2], tree.joints[4]
    np.testing.assert_allclose([float(femur.stiffness), float(knee.stiffness), float(toe.stiffness)],
                               [3.4157, 2.2361, 0.5774], atol=5e-5)
    np.testing.assert_allclose([float(knee.damping), float(toe.damping), float(femur.damping)],
                               [2.0 + 2.0, 2.0 + 0.1333, 2.0], atol=5e-5)  # the limits' damping, always on
    assert knee.range == (0.0, 2.3) and toe.range == (-0.6, 0.6) and float(knee.armature) == 0.05
    np.testing.assert_allclose(np.asarray(tree.limits.ke), [200.0, 13.333, 13.333] * 2, atol=5e-4)
    q = tree.neutral()
    com = np.asarray(tree.mass) @ np.asarray(lg.com_positions(tree, q)) / 37.0
    from lagrange.kinematics import contact_point_positions
    lowest = float(np.min(np.asarray(contact_point_positions(tree, q))[:, 2]))
    assert abs(com[2] - 0.742) < 5e-4 and abs(lowest - 0.0314) < 5e-5 and abs(com[0]) < 0.05
    exact = snu_tree(dflex_inertia=False).bodies[1].inertia  # the rigid body's R I R^T: products of inertia
    assert 1e-3 < np.max(np.abs(np.asarray(exact) - np.diag(np.diag(np.asarray(exact))))) < 2e-3


def test_the_muscles_kept_and_their_order(tree):
    """152 of the 284 units (every waypoint on the lower body), in file order, 636 waypoints, 198 segments joining two
    bodies; tensions ``0.36 f0`` from 16.2 to 645.5 N (19,857 N in all)."""
    names = [mu.name for mu in tree.muscles]
    assert names[:3] == ["L_Adductor_Brevis", "R_Adductor_Brevis", "L_Adductor_Brevis1"] and len(names) == 152
    assert sum(n.startswith("L_") for n in names) == sum(n.startswith("R_") for n in names) == 76
    assert sum(len(mu.bodies) for mu in tree.muscles) == 636
    assert sum(a != b for mu in tree.muscles for a, b in zip(mu.bodies, mu.bodies[1:])) == 198
    strength = np.array([float(mu.strength) for mu in tree.muscles])
    np.testing.assert_allclose([strength.min(), strength.max(), strength.sum()], [16.2, 645.462, 19857.0], atol=1.0)


def _without_contact_and_limits(tree):
    """The skeleton with its muscles, MuJoCo's ball springs, no contact points and no ranges: what MJCF can state."""
    bodies = []
    for b in tree.bodies:
        joints = [lg.Ball(damping=j.damping, armature=j.armature, stiffness=j.stiffness, name=j.name)
                  if isinstance(j, DFlexBall) else
                  lg.Hinge(j.axis, damping=j.damping, armature=j.armature, stiffness=j.stiffness, name=j.name)
                  if isinstance(j, lg.Hinge) else j for j in b.joints]
        bodies.append(lg.Body(b.mass, b.inertia, b.com, joints=joints, parent=b.parent, pos=b.pos, quat=b.quat,
                              name=b.name))
    return lg.Tree(bodies, tree.gravity, muscles=tree.muscles)


def test_the_skeleton_and_its_152_muscles_equal_mujoco(tree):
    """Written as MJCF (spatial tendons through sites, tendon actuators of gain ``-0.36 f0``): every muscle's length
    is MuJoCo's ``ten_length``, their forces its ``qfrc_actuator`` and the accelerations its ``qacc``, at random
    poses, velocities and activations."""
    import mujoco

    free = _without_contact_and_limits(tree)
    model = mujoco.MjModel.from_xml_string(to_mjcf(free))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    terms = jax.jit(lambda q, qd, u: (lg.muscle_lengths(free, q), lg.forward_dynamics(free, q, qd, u),
                                      lg.forward_dynamics(free, q, qd, u) - lg.forward_dynamics(free, q, qd, 0 * u)))
    for _ in range(3):
        q = np.array(free.neutral())
        for k in range(1, 11):  # every ball's quaternion and hinge's angle moved
            a, n = free.qadr[k], free.joints[k].nq
            q[a: a + n] = q[a: a + n] + rng.uniform(-0.3, 0.3, n)
        qd, u = rng.uniform(-1, 1, free.nv), rng.uniform(0, 1, free.m)
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, qd, u
        mujoco.mj_forward(model, data)
        L, qdd, _ = terms(*(jnp.asarray(x) for x in (q, qd, u)))
        assert rel(L, data.ten_length) <= 1e-12
        assert rel(qdd, data.qacc) <= 1e-10
        M = np.zeros((free.nv, free.nv))
        mujoco.mj_fullM(model, data, M)
        tau = M @ (np.asarray(qdd) - np.asarray(lg.forward_dynamics(free, *(jnp.asarray(x) for x in (q, qd)),
                                                                     jnp.zeros(free.m))))
        assert rel(tau, data.qfrc_actuator) <= 1e-10


def test_dflex_s_ball_spring_pulls_by_the_quaternion_s_vector_part_and_conserves_energy():
    """A pendulum on a :class:`DFlexBall` spring: the spring's generalized force is ``-ke (x, y, z)`` of the
    quaternion (half MuJoCo's rotation vector near rest), and with no gravity or damping its energy ``2 ke (1 - w)``
    plus the kinetic is conserved to RK4's error."""
    ball = DFlexBall(stiffness=3.0)
    tree = lg.Tree([lg.Body(1.0, (0.1, 0.2, 0.3), (0.0, 0.0, -0.5), joints=[ball])], gravity=(0.0, 0.0, 0.0))
    q = jnp.asarray([0.9, 0.3, -0.2, 0.1]) / jnp.linalg.norm(jnp.asarray([0.9, 0.3, -0.2, 0.1]))
    np.testing.assert_allclose(lg.bias_forces(tree, q, jnp.zeros(3)), 3.0 * q[1:], rtol=1e-14)
    _, V = lg.energy(tree, q, jnp.zeros(3))
    assert math.isclose(float(V), 2 * 3.0 * (1 - float(q[0])), rel_tol=1e-14)
    traj = lg.simulate(tree, q, jnp.asarray([0.5, -1.0, 0.3]), None, 1e-3, lg.RK4(), steps=2000)
    E = [sum(lg.energy(tree, traj.q[i], traj.qd[i])) for i in (0, -1)]
    assert abs(float(E[1] - E[0])) <= 1e-9 * float(E[0])


def test_the_observation_the_reward_and_the_early_end_by_hand():
    task = SNUHumanoid.diffrl()
    q = np.array(task.start)
    q[:3] = (2.0, 0.5, 0.9)
    qd = np.zeros(24)
    qd[:3] = (1.5, -0.2, 0.1)  # the pelvis's velocity in the world
    qd[3:6] = (0.0, 0.3, 0.0)  # its angular velocity in its own frame: about MASS's y, the world's z at the start
    s = TaskState(jnp.asarray(q), jnp.asarray(qd))
    obs = np.asarray(task.observe(s))
    assert obs.shape == (53,) and obs[0] == 0.9
    np.testing.assert_allclose(obs[1:5], (0.5, 0.5, 0.5, 0.5))
    np.testing.assert_allclose(obs[5:8], (1.5, -0.2, 0.1))
    np.testing.assert_allclose(obs[8:11], (0.0, 0.0, 0.3), atol=1e-15)  # turned into the world
    np.testing.assert_allclose(obs[11:33], q[7:])
    assert obs[51] == pytest.approx(1.0)  # upright
    heading = 9998.0 / math.hypot(9998.0, 0.5)  # facing +x, the target at (10000, 0)
    assert obs[52] == pytest.approx(heading, rel=1e-12)
    action = jnp.full(152, 0.5)  # activations 0.75
    r = task.reward(s, action, s)
    assert float(r) == pytest.approx(1.5 + 0.1 + heading - 0.001 * 152 * 0.75, rel=1e-12)
    np.testing.assert_allclose(task.controls(jnp.asarray([-1.0, 0.0, 1.0])), [0.0, 0.5, 1.0])
    assert not task.terminated(s) and task.terminated(TaskState(s.q.at[2].set(0.45), s.qd))


def test_the_reset_draws_dflex_s_noise():
    """The pelvis within 0.1 m of its start per axis, turned by at most 7.5 degrees, the legs at rest (no joint
    noise), every one of DFlex's velocities within 0.25 (the pelvis's angular velocity in the world)."""
    task = SNUHumanoid.diffrl()
    states = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 256))
    q, qd = np.asarray(states.q), np.asarray(states.qd)
    assert states.action is None
    assert np.all(np.abs(q[:, :3] - np.asarray(task.start[:3])) <= 0.1)
    turn = np.abs(np.sum(q[:, 3:7] * np.asarray(task.start[3:7]), axis=1))  # |cos(angle / 2)|
    assert np.all(2 * np.arccos(np.clip(turn, -1, 1)) <= math.pi / 24 + 1e-12)
    np.testing.assert_array_equal(q[:, 7:], np.broadcast_to(np.asarray(task.start[7:]), q[:, 7:].shape))
    assert np.all(np.abs(qd[:, 6:]) <= 0.25) and np.max(np.abs(qd[:, 6:])) > 0.24
    w_world = np.einsum("bij,bj->bi", np.asarray(jax.vmap(lambda x: lg.math.spatial.quat_to_matrix(x))(
        states.q[:, 3:7])), qd[:, 3:6])
    assert np.all(np.abs(w_world) <= 0.25 + 1e-12)


def test_shac_s_window_and_its_gradient_run_through_the_muscles():
    """SHAC's window on the SNU task (2 environments, 2 control steps of 4 substeps, the mass matrix every 2): the loss
    and its gradient with respect to the actor are finite, and the gradient reaches the actor through the muscles."""
    from optim.shac.losses import actor_loss
    from policies import Actor, Critic
    from lagrange.tasks.snu import SNU_SOLVER
    import dataclasses

    task = SNUHumanoid.diffrl(substeps=4, solver=dataclasses.replace(SNU_SOLVER, mass_matrix_every=2), horizon=10)
    actor, critic = Actor.for_task(task, units=(8,)), Critic(task.observation_size, (8,), key=jax.random.PRNGKey(1))
    s = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 2))

    @jax.jit
    def grad(actor):
        return jax.value_and_grad(lambda a: actor_loss(a, critic, None, task, s, jnp.zeros(2, jnp.int32), jnp.zeros(2),
                                                       jax.random.PRNGKey(3), short_horizon=2, horizon=10,
                                                       gamma=0.99)[0])(actor)

    loss, g = grad(actor)
    leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(g) if hasattr(x, "shape")]
    assert np.isfinite(float(loss)) and all(np.all(np.isfinite(x)) for x in leaves)
    assert max(float(np.max(np.abs(x))) for x in leaves) > 0
