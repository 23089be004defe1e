"""DFlex's Ant and Humanoid (``lagrange.tasks.Ant.diffrl``, ``Humanoid.diffrl``) against their definitions: the
bodies against MuJoCo's compiler on the assets' geometry under DFlex's loading rules (masses, centres of mass, the
contact points and the joints' motion at random poses) and against DFlex's (ODE's) capsule formula written out;
DFlex's loader parameters; the observation, the reward and the early end on states built by hand; the reset's noise
as DFlex draws it; the last action carried in the state."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop import from_mjcf
from lagrange.tasks import Ant, Humanoid, TaskState
from lagrange.tasks.locomotion import DFLEX_SOLVER
from lagrange.tasks.locomotion3d import HUMANOID_SOLVER

# The SHAC release's envs/assets/ant.xml (its geometry, every geom at density 1000 as DFlex's loader weighs them).
ANT_XML = """
<mujoco model="ant">
  <compiler angle="degree"/>
  <default><geom density="1000" conaffinity="0"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="40 40 1" conaffinity="1"/>
    <body name="torso" pos="0 0 0.75">
      <freejoint/>
      <geom type="sphere" size="0.25"/>
      <geom type="capsule" fromto="0 0 0 0.2 0.2 0" size="0.08"/>
      <geom type="capsule" fromto="0 0 0 -0.2 0.2 0" size="0.08"/>
      <geom type="capsule" fromto="0 0 0 -0.2 -0.2 0" size="0.08"/>
      <geom type="capsule" fromto="0 0 0 0.2 -0.2 0" size="0.08"/>
      <body pos="0.2 0.2 0"><joint name="hip_1" axis="0 0 1" range="-40 40" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0.2 0.2 0" size="0.08"/>
        <body pos="0.2 0.2 0"><joint name="ankle_1" axis="-1 1 0" range="30 100" limited="true"/>
          <geom type="capsule" fromto="0 0 0 0.4 0.4 0" size="0.08"/></body></body>
      <body pos="-0.2 0.2 0"><joint name="hip_2" axis="0 0 1" range="-40 40" limited="true"/>
        <geom type="capsule" fromto="0 0 0 -0.2 0.2 0" size="0.08"/>
        <body pos="-0.2 0.2 0"><joint name="ankle_2" axis="1 1 0" range="-100 -30" limited="true"/>
          <geom type="capsule" fromto="0 0 0 -0.4 0.4 0" size="0.08"/></body></body>
      <body pos="-0.2 -0.2 0"><joint name="hip_3" axis="0 0 1" range="-40 40" limited="true"/>
        <geom type="capsule" fromto="0 0 0 -0.2 -0.2 0" size="0.08"/>
        <body pos="-0.2 -0.2 0"><joint name="ankle_3" axis="-1 1 0" range="-100 -30" limited="true"/>
          <geom type="capsule" fromto="0 0 0 -0.4 -0.4 0" size="0.08"/></body></body>
      <body pos="0.2 -0.2 0"><joint name="hip_4" axis="0 0 1" range="-40 40" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0.2 -0.2 0" size="0.08"/>
        <body pos="0.2 -0.2 0"><joint name="ankle_4" axis="1 1 0" range="30 100" limited="true"/>
          <geom type="capsule" fromto="0 0 0 0.4 -0.4 0" size="0.08"/></body></body>
    </body>
  </worldbody>
</mujoco>
"""


def _random_q(key, n):
    kq, kj = jax.random.split(key)
    quat = jax.random.normal(kq, (n, 4))
    quat = quat / jnp.linalg.norm(quat, axis=-1, keepdims=True)
    pos = jax.random.uniform(kj, (n, 3), minval=-1.0, maxval=1.0)
    joints = jax.random.uniform(jax.random.fold_in(kj, 1), (n, 8), minval=-1.5, maxval=1.5)
    return jnp.concatenate([pos, quat, joints], axis=-1)


def test_the_bodies_match_the_asset_compiled_by_mujoco():
    """Masses and centres of mass as MuJoCo weighs the asset at density 1000 (the same sphere and capsule volumes),
    every contact point and body origin where MuJoCo's kinematics puts them at random poses, the joints' ranges."""
    ant = Ant.diffrl().chain
    ref = from_mjcf(ANT_XML, contact=lg.PenaltyContact(4e4, 1e4, 3e3, 0.75),
                    limits=lg.PenaltyLimits(1e3))
    np.testing.assert_allclose(np.asarray(ant.mass), np.asarray(ref.mass), rtol=1e-12)
    assert abs(float(jnp.sum(ant.mass)) - 182.176014) < 1e-5
    np.testing.assert_allclose(np.stack([b.com for b in ant.bodies]), np.stack([b.com for b in ref.bodies]),
                               atol=1e-12)
    assert [j.range for j in ant.joints[1:]] == [j.range for j in ref.joints[1:]]
    _same_points_and_origins(ant, ref, _random_q(jax.random.PRNGKey(0), 8), 25)


def _same_points_and_origins(tree, ref, q, points):
    """The same set of contact points (in any order) and the same body origins at the poses ``q``."""

    @jax.jit  # one program for both trees
    def where(q):
        return [(jax.vmap(lambda x: lg.kinematics.contact_point_positions(t, x))(q), lg.positions(t, q))
                for t in (tree, ref)]

    (ours, o1), (theirs, o2) = jax.tree_util.tree_map(np.asarray, where(q))
    assert ours.shape == theirs.shape == (len(q), points, 3)
    key = lambda p: np.lexsort(np.round(p.T, 9)[::-1])
    for a, b in zip(ours, theirs):
        np.testing.assert_allclose(a[key(a)], b[key(b)], atol=1e-12)
    np.testing.assert_allclose(o1, o2, atol=1e-12)


def test_the_inertias_are_dflex_s_capsules():
    """A foot is one capsule (radius 0.08, length 0.4 sqrt 2): its principal moments about its centre are DFlex's
    (ODE's) formula written out, the axial one along the capsule."""
    r, length, rho = 0.08, 0.4 * math.sqrt(2.0), 1000.0
    ms, mc = rho * 4 / 3 * math.pi * r**3, rho * math.pi * r * r * length
    transverse = mc * (r * r / 4 + length**2 / 12) + ms * (0.4 * r * r + 0.375 * r * length + 0.25 * length**2)
    axial = (mc / 2 + 0.4 * ms) * r * r
    foot = Ant.diffrl().chain.bodies[2]
    assert abs(float(foot.mass) - (ms + mc)) < 1e-12
    np.testing.assert_allclose(np.linalg.eigvalsh(np.asarray(foot.inertia)), sorted([axial, transverse, transverse]),
                               rtol=1e-12)
    u = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    assert abs(u @ np.asarray(foot.inertia) @ u - axial) < 1e-12


def test_dflex_s_loader_parameters():
    tree = Ant.diffrl().chain
    free, *hinges = tree.joints
    assert isinstance(free, lg.Free) and float(free.armature) == 0 and float(free.damping) == 0
    assert len(hinges) == 8 and all(float(j.damping) == 11.0 and float(j.armature) == 0.05 for j in hinges)
    assert all(float(j.stiffness) == 0 for j in hinges)
    assert [m.joint for m in tree.motors] == list(range(1, 9)) and all(float(m.gear) == 200 for m in tree.motors)
    c, lim = tree.contact, tree.limits
    assert (float(c.ke), float(c.kd), float(c.kf), float(c.mu)) == (4e4, 1e4, 3e3, 0.75)
    assert (float(lim.ke), float(lim.kd)) == (1e3, 0.0)  # the limit damping 10 acts always: in the joints' damping
    assert sum(len(b.contacts) for b in tree.bodies) == 25
    assert Ant.diffrl().solver == DFLEX_SOLVER and not DFLEX_SOLVER.checkpoint_substeps
    # the humanoid's: DFlex's, each of its 48 substeps recomputed in the backward pass (test_integrate: no change)
    assert Humanoid.__dataclass_fields__["solver"].default == HUMANOID_SOLVER
    assert HUMANOID_SOLVER == lg.SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True,
                                                   checkpoint_substeps=True)


def _state(psi=0.0, pos=(0.0, 0.0, 0.6), v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0), action=None):
    quat = [math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)]  # turned by psi about z
    q = jnp.asarray([*pos, *quat, 0.1, 1.0, -0.1, -1.0, 0.2, -1.0, -0.2, 1.0])
    qd = jnp.asarray([*v, *w] + [0.5 * k for k in range(8)])
    return TaskState(q, qd, jnp.zeros(8) if action is None else jnp.asarray(action))


def test_observation_reward_and_early_end_on_states_built_by_hand():
    task = Ant.diffrl()
    psi = 0.3
    s = _state(psi, pos=(1.0, 2.0, 0.6), v=(2.0, -1.0, 0.5), w=(0.1, 0.2, 0.3), action=np.linspace(-1, 1, 8))
    obs = np.asarray(task.observe(s))
    assert obs.shape == (37,) == (task.observation_size,)
    c, sn = math.cos(psi), math.sin(psi)
    R = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(obs[0], 0.6)
    np.testing.assert_allclose(obs[1:5], [math.cos(psi / 2), 0, 0, math.sin(psi / 2)], atol=1e-7)
    np.testing.assert_allclose(obs[5:8], [2.0, -1.0, 0.5])
    np.testing.assert_allclose(obs[8:11], R @ [0.1, 0.2, 0.3], atol=1e-7)  # the angular velocity in the world
    np.testing.assert_allclose(obs[11:19], np.asarray(s.q[7:]))
    np.testing.assert_allclose(obs[19:27], 0.1 * np.asarray(s.qd[6:]), atol=1e-7)
    np.testing.assert_allclose(obs[27], 1.0, atol=1e-7)  # upright
    target = np.array([10000.0 - 1.0, -2.0])
    np.testing.assert_allclose(obs[28], R[:2, 0] @ target / np.linalg.norm(target), atol=1e-6)
    np.testing.assert_allclose(obs[29:], np.linspace(-1, 1, 8), atol=1e-7)
    # reward of the state landed in: v_x + 0.1 up + heading + (height - 0.27); no action cost
    upright = _state(0.0, pos=(0.0, 0.0, 0.6), v=(2.0, 0.0, 0.0))
    r = float(task.reward(upright, jnp.ones(8), upright))
    assert abs(r - (2.0 + 0.1 + 1.0 + 0.33)) < 1e-6
    assert not bool(task.terminated(upright))
    assert bool(task.terminated(_state(pos=(0.0, 0.0, 0.26))))
    # on its back: up = -1, heading -1 (turned by pi about x)
    flipped = TaskState(upright.q.at[3:7].set(jnp.array([0.0, 1.0, 0.0, 0.0])), upright.qd, upright.action)
    assert abs(float(task.reward(flipped, jnp.zeros(8), flipped)) - (2.0 - 0.1 + 1.0 + 0.33)) < 1e-6


def test_the_reset_draws_dflex_s_noise():
    task = Ant.diffrl()
    s = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(3), 2048))
    q, qd = np.asarray(s.q, float), np.asarray(s.qd, float)
    assert np.all(np.asarray(s.action) == 0)
    start = np.asarray(task.start)
    for lo, hi, bound in ((0, 3, 0.1), (7, 15, 0.2)):
        dev = q[:, lo:hi] - start[lo:hi]
        assert np.all(np.abs(dev) <= bound) and np.all(np.abs(dev).max(0) > 0.98 * bound)
    np.testing.assert_allclose(np.linalg.norm(q[:, 3:7], axis=-1), 1.0, atol=1e-6)
    angle = 2 * np.arccos(np.clip(np.abs(q[:, 3]), 0, 1))
    assert angle.max() <= math.pi / 24 + 1e-5 and angle.max() > 0.95 * math.pi / 24
    # DFlex's velocities: the world angular velocity w and the world twist v - w x p, each U(-0.25, 0.25)
    qw, qx, qy, qz = q[:, 3:7].T  # the rotation of each quaternion, written out
    R = np.stack([np.stack([1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)], -1),
                  np.stack([2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)], -1),
                  np.stack([2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)], -1)], -2)
    w = np.einsum("bij,bj->bi", R, qd[:, 3:6])
    twist = qd[:, 0:3] - np.cross(w, q[:, 0:3])
    for x in (w, twist, qd[:, 6:]):
        assert np.all(np.abs(x) <= 0.25 + 1e-6) and np.all(np.abs(x).max(0) > 0.24)
        assert np.all(np.abs(x.mean(0)) < 0.02)


def test_a_state_without_its_action_is_refused_by_name():
    task = Ant.diffrl()
    s = task.reset(jax.random.PRNGKey(0))
    with pytest.raises(ValueError, match=r"Ant\.observe: state\.action is None; this task observes the last action"):
        task.observe(TaskState(s.q, s.qd))
    with pytest.raises(ValueError, match=r"Ant: state\.action must have shape \(m,\) = \(8,\) or be None, got \(3,\)"):
        task.observe(TaskState(s.q, s.qd, jnp.zeros(3)))


def test_a_step_carries_the_clipped_action():
    task = Ant.diffrl()
    s = task.reset(jax.random.PRNGKey(0))
    a = jnp.array([2.0, -3.0, 0.5, 0.0, 0.1, -0.2, 1.0, -1.0])
    s1 = jax.jit(lambda s, a: task.step(s, a))(s, a)
    np.testing.assert_allclose(np.asarray(s1.action), np.clip(np.asarray(a), -1, 1))
    assert s1.q.shape == (15,) and s1.qd.shape == (14,)
    np.testing.assert_allclose(float(jnp.linalg.norm(s1.q[3:7])), 1.0, atol=1e-6)


# The SHAC release's humanoid.xml as DFlex's loader reads it: every geom at density 1000, the body quats dropped, each
# joint's own stiffness, damping and armature (the knees: parse_mjcf's defaults 5, 0.1, 0.007).
HUMANOID_XML = """
<mujoco model="humanoid">
  <compiler angle="degree"/>
  <default><geom density="1000" conaffinity="0"/><joint limited="true" stiffness="5" damping="0.1" armature="0.007"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="100 100 .2" conaffinity="1"/>
    <body name="torso" pos="0 0 1.35">
      <freejoint/>
      <geom type="capsule" fromto="0 -.07 0 0 .07 0" size=".07"/>
      <geom type="capsule" fromto="-.01 -.06 -.12 -.01 .06 -.12" size=".06"/>
      <geom type="sphere" size=".09" pos="0 0 .19"/>
      <body name="lower_waist" pos="-.01 0 -.260">
        <geom type="capsule" fromto="0 -.06 0 0 .06 0" size=".06"/>
        <joint name="abdomen_z" pos="0 0 .065" axis="0 0 1" range="-45 45" damping="5" stiffness="20" armature=".02"/>
        <joint name="abdomen_y" pos="0 0 .065" axis="0 1 0" range="-75 30" damping="5" stiffness="20" armature=".01"/>
        <body name="pelvis" pos="0 0 -.165">
          <joint name="abdomen_x" pos="0 0 .1" axis="1 0 0" range="-35 35" damping="5" stiffness="10" armature=".01"/>
          <geom type="capsule" fromto="-.02 -.07 0 -.02 .07 0" size=".09"/>
          <body name="right_thigh" pos="0 -.1 -.04">
            <joint name="right_hip_x" axis="1 0 0" range="-25 5" damping="5" stiffness="10" armature=".01"/>
            <joint name="right_hip_z" axis="0 0 1" range="-60 35" damping="5" stiffness="10" armature=".01"/>
            <joint name="right_hip_y" axis="0 1 0" range="-80 20" damping="5" stiffness="20" armature=".01"/>
            <geom type="capsule" fromto="0 0 0 0 .01 -.34" size=".06"/>
            <body name="right_shin" pos="0 .01 -.403">
              <joint name="right_knee" pos="0 0 .02" axis="0 -1 0" range="-160 2"/>
              <geom type="capsule" fromto="0 0 0 0 0 -.3"  size=".049"/>
              <body name="right_foot" pos="0 0 -.39">
                <joint name="right_ankle_y" pos="0 0 .08" axis="0 1 0" range="-50 50" damping="1" stiffness="2"
                       armature=".006"/>
                <joint name="right_ankle_x" pos="0 0 .08" axis="1 0 .5" range="-50 50" damping="1" stiffness="2"
                       armature=".006"/>
                <geom type="capsule" fromto="-.07 -.02 0 .14 -.04 0" size=".027"/>
                <geom type="capsule" fromto="-.07 0 0 .14  .02 0" size=".027"/>
              </body>
            </body>
          </body>
          <body name="left_thigh" pos="0 .1 -.04">
            <joint name="left_hip_x" axis="-1 0 0" range="-25 5" damping="5" stiffness="10" armature=".01"/>
            <joint name="left_hip_z" axis="0 0 -1" range="-60 35" damping="5" stiffness="10" armature=".01"/>
            <joint name="left_hip_y" axis="0 1 0" range="-80 20" damping="5" stiffness="20" armature=".01"/>
            <geom type="capsule" fromto="0 0 0 0 -.01 -.34" size=".06"/>
            <body name="left_shin" pos="0 -.01 -.403">
              <joint name="left_knee" pos="0 0 .02" axis="0 -1 0" range="-160 2"/>
              <geom type="capsule" fromto="0 0 0 0 0 -.3"  size=".049"/>
              <body name="left_foot" pos="0 0 -.39">
                <joint name="left_ankle_y" pos="0 0 .08" axis="0 1 0" range="-50 50" damping="1" stiffness="2"
                       armature=".006"/>
                <joint name="left_ankle_x" pos="0 0 .08" axis="1 0 .5" range="-50 50" damping="1" stiffness="2"
                       armature=".006"/>
                <geom type="capsule" fromto="-.07 .02 0 .14 .04 0" size=".027"/>
                <geom type="capsule" fromto="-.07 0 0 .14  -.02 0" size=".027"/>
              </body>
            </body>
          </body>
        </body>
      </body>
      <body name="right_upper_arm" pos="0 -.17 .06">
        <joint name="right_shoulder1" axis="2 1 1" range="-60 60" damping="5" stiffness="10" armature=".01"/>
        <joint name="right_shoulder2" axis="0 -1 1" range="-60 60" damping="5" stiffness="10" armature=".01"/>
        <geom type="capsule" fromto="0 0 0 .16 -.16 -.16" size=".04 .16"/>
        <body name="right_lower_arm" pos=".18 -.18 -.18">
          <joint name="right_elbow" axis="0 -1 1" range="-90 50" damping="1" stiffness="2" armature=".006"/>
          <geom type="capsule" fromto=".01 .01 .01 .17 .17 .17" size=".031"/>
          <geom type="sphere" size=".04" pos=".18 .18 .18"/>
        </body>
      </body>
      <body name="left_upper_arm" pos="0 .17 .06">
        <joint name="left_shoulder1" axis="-2 1 -1" range="-60 60" damping="5" stiffness="10" armature=".01"/>
        <joint name="left_shoulder2" axis="0 -1 -1" range="-60 60" damping="5" stiffness="10" armature=".01"/>
        <geom type="capsule" fromto="0 0 0 .16 .16 -.16" size=".04 .16"/>
        <body name="left_lower_arm" pos=".18 .18 -.18">
          <joint name="left_elbow" axis="0 -1 -1" range="-90 50" damping="1" stiffness="2" armature=".006"/>
          <geom type="capsule" fromto=".01 -.01 .01 .17 -.17 .17" size=".031"/>
          <geom type="sphere" size=".04" pos=".18 -.18 .18"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_the_humanoid_matches_its_asset_compiled_by_mujoco():
    """Masses, centres of mass, contact points and body origins at random poses as MuJoCo compiles the asset under
    DFlex's rules; each hinge's stiffness, armature and range, and its damping plus DFlex's 10; the gains."""
    tree = Humanoid.diffrl().chain
    ref = from_mjcf(HUMANOID_XML, contact=lg.PenaltyContact(2e4, 5e3, 1e3, 0.75), limits=lg.PenaltyLimits(1e3))
    np.testing.assert_allclose(np.asarray(tree.mass), np.asarray(ref.mass), rtol=1e-12)
    np.testing.assert_allclose(np.stack([b.com for b in tree.bodies]), np.stack([b.com for b in ref.bodies]),
                               atol=1e-12)
    ours, theirs = tree.joints[1:], ref.joints[1:]
    assert len(ours) == 21 and [j.range for j in ours] == [j.range for j in theirs]
    for field in ("stiffness", "armature", "pos"):
        np.testing.assert_allclose([np.asarray(getattr(j, field)) for j in ours],
                                   [np.asarray(getattr(j, field)) for j in theirs], atol=1e-12)
    np.testing.assert_allclose([float(j.damping) for j in ours], [float(j.damping) + 10 for j in theirs])
    np.testing.assert_allclose([float(m.gear) for m in tree.motors],
                               [70, 70, 70, 70, 70, 210, 140, 35, 35, 70, 70, 210, 140, 35, 35, 35, 35, 70, 35, 35, 70])
    q = jnp.concatenate([_random_q(jax.random.PRNGKey(1), 6)[:, :7],
                         jax.random.uniform(jax.random.PRNGKey(2), (6, 21), minval=-1.0, maxval=1.0)], axis=-1)
    _same_points_and_origins(tree, ref, q, 35)


def test_the_humanoid_s_reward_and_early_end():
    task = Humanoid.diffrl()
    assert task.observation_size == 76 and task.action_size == 21 and task.substeps == 48
    q = jnp.asarray(task.start).at[2].set(0.9)
    s = TaskState(q, jnp.zeros(27).at[0].set(1.5), jnp.zeros(21))
    a = jnp.full(21, 0.5)
    # upright, heading +x: 1.5 + 0.1 + 1 + 10 * min(0.9 - 0.84, 0.1) - 0.002 * 21 * 0.25
    assert abs(float(task.reward(s, a, s)) - (1.5 + 0.1 + 1.0 + 0.6 - 0.0105)) < 1e-5
    low = s._replace(q=q.at[2].set(0.8))  # below the standing height: -200 x^2
    assert abs(float(task.reward(low, a, low)) - (1.5 + 0.1 + 1.0 - 200 * 0.04**2 - 0.0105)) < 1e-5
    assert not bool(task.terminated(low)) and bool(task.terminated(s._replace(q=q.at[2].set(0.73))))
    assert abs(float(task.reward(s, 3 * a, s)) - (1.5 + 0.1 + 1.0 + 0.6 - 0.042)) < 1e-5  # the action clipped first


def test_shac_s_window_runs_through_a_3d_task():
    """SHAC's window on an ant of one leg (its torso on the free joint, one driven hinge; 2 environments, 3 steps, 2
    substeps), one about to fall: the state with its last action goes through the rollout and the reset, the loss is
    finite. (Gradients through 3-D contact: rbda/test_contact.py.)"""
    from optim.shac.losses import actor_loss
    from policies import Actor, Critic

    task = Ant(_one_leg(), start=(0, 0, 0.5, 1, 0, 0, 0, 0.3), substeps=2, horizon=100)
    actor, critic = Actor.for_task(task, units=(8,)), Critic(task.observation_size, (8,), key=jax.random.PRNGKey(1))

    @jax.jit
    def window(key):
        s = jax.vmap(task.reset)(jax.random.split(key, 2))
        s = s._replace(q=s.q.at[0, 2].set(0.28), qd=s.qd.at[0, 2].set(-3.0))  # the first about to fall below 0.27
        return actor_loss(actor, critic, None, task, s, jnp.zeros(2, jnp.int32), jnp.zeros(2), jax.random.PRNGKey(3),
                          short_horizon=3, horizon=100, gamma=0.99)

    loss, win = window(jax.random.PRNGKey(0))
    assert np.isfinite(float(loss)) and np.all(np.isfinite(np.asarray(win.rewards)))
    assert bool(np.asarray(win.dones)[:, 0].any()) and int(win.progress[0]) < 3  # fell and restarted
    assert win.env_state.action.shape == (2, 1) and win.env_state.q.shape == (2, 8)


def _one_leg():
    """An ant of one leg: its torso on the free joint, one driven hinge, the ant's contact."""
    from lagrange.tasks.dflex_trees import dflex_body

    return lg.Tree([dflex_body([((0, 0, 0), 0.25)], joints=[lg.Free()], pos=(0, 0, 0.5)),
                    dflex_body(capsules=[((0, 0, 0), (0.4, 0, 0), 0.08)], parent=0, pos=(0.2, 0, 0),
                               joints=[lg.Hinge((0, 1, 0), damping=11.0, armature=0.05)])],
                   motors=[lg.Motor(1, 200.0)], contact=lg.PenaltyContact(4e4, 1e4, 3e3, 0.75))

