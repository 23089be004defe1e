"""Spatial trees (lagrange.model.tree, lagrange.model.joints, lagrange.rbda) against MuJoCo C, finite differences and
conservation laws.

- Every 3-D model users hold (Gymnasium's ant, humanoid, humanoidstandup and pusher; dm_control's humanoid, humanoid_CMU
  with its 56 hinges and finger; Brax's ant and humanoid), a chain of ball joints and a URDF arm with revolute,
  continuous and prismatic joints about tilted axes (``tests/assets/tilted_arm.urdf``), read by ``from_mjcf`` with
  ``limits="ignore", contact="ignore"`` and compared with MuJoCo in free flight (constraints disabled): M
  (``mj_fullM``), ``qfrc_bias - qfrc_passive`` and ``qacc`` at random states with random unit quaternions and speeds
  up to 3 rad/s, to 1e-10 relative (float64 round-off amplified by the solve: measured <= 5e-14); 30 steps of MuJoCo's
  semi-implicit Euler (``mj_step``, ``integrator="Euler"``) to 1e-9. MuJoCo 4.0's RK4 on a free or ball joint is not
  the scheme it publishes (``mj_RungeKutta``), so the RK4 models are stepped with its Euler; lagrange's RK4 on a
  tree is Runge-Kutta-Munthe-Kaas and is checked for its order instead (:func:`test_rk4_is_fourth_order_on_rotations`).
- Gradients through the exponential map at zero angular velocity (where peers' turned NaN) are finite and equal
  central differences.
- A free-floating humanoid without gravity or damping conserves its momentum (to round-off: no external force) and
  its energy at its solver's order.
- Bad input and refusals name what is wrong.
"""

from __future__ import annotations

import pathlib

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop.mjcf import from_mjcf, to_mjcf
from lagrange.model.joints import Ball, Free, Hinge, Slide
from lagrange.model.tree import Body, Motor, Tree
from tests.helpers import ROOT, mujoco_terms, rel

EXACT = 1e-10
TRAJECTORY = 1e-9
GYM = pathlib.Path(__import__("gymnasium").__file__).parent / "envs" / "mujoco" / "assets"
DMC = pathlib.Path(__import__("dm_control").__file__).parent / "suite"
BRAX = pathlib.Path(__import__("importlib").util.find_spec("brax").submodule_search_locations[0]) / "envs" / "assets"
BALLS = """<mujoco><option timestep="0.005"/><worldbody><body name="b0" pos="0 0 1"><joint type="ball" damping="0.3"
  armature="0.01"/><geom type="capsule" fromto="0 0 0 0.1 0.05 -0.4" size="0.04"/><body name="b1" pos="0.1 0.05 -0.4">
  <joint type="ball" pos="0 0 0.02" stiffness="2"/><geom type="capsule" fromto="0 0 0 -0.05 0.1 -0.3" size="0.03"/>
  <body name="b2" pos="-0.05 0.1 -0.3" quat="0.9 0.1 0.3 0.2"><joint type="ball"/>
  <geom type="box" size="0.05 0.08 0.1" pos="0.02 0 -0.1"/><body name="b3" pos="0 0 -0.2"><joint name="h" axis="0 1 0"/>
  <geom type="sphere" size="0.05" pos="0.05 0 -0.05"/></body></body></body></body></worldbody>
  <actuator><motor joint="h" gear="3"/></actuator></mujoco>"""
MODELS = {
    "gymnasium/ant": GYM / "ant.xml", "gymnasium/humanoid": GYM / "humanoid.xml",
    "gymnasium/humanoidstandup": GYM / "humanoidstandup.xml", "gymnasium/pusher": GYM / "pusher.xml",
    "dm_control/humanoid": DMC / "humanoid.xml", "dm_control/humanoid_CMU": DMC / "humanoid_CMU.xml",
    "dm_control/finger": DMC / "finger.xml", "brax/ant": BRAX / "ant.xml", "brax/humanoid": BRAX / "humanoid.xml",
    "balls": BALLS, "urdf/tilted_arm": ROOT / "tests" / "assets" / "tilted_arm.urdf",
}


def _compile(source):
    return (mujoco.MjModel.from_xml_string(source) if isinstance(source, str)
            else mujoco.MjModel.from_xml_path(str(source)))


def free_flight(name):
    """MuJoCo's model with every constraint disabled (and Euler), and the tree read from it as a user reads it."""
    model = _compile(MODELS[name])
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    tree = from_mjcf(model, limits="ignore", contact="ignore")
    return model, tree


def random_state(model, rng, speed=3.0):
    """qpos0 moved by up to 1 (hinges, slides by up to 0.3 m), random unit quaternions, velocities up to ``speed``."""
    q = np.array(model.qpos0, float)
    for j in range(model.njnt):
        a, kind = model.jnt_qposadr[j], model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            q[a: a + 3] += rng.uniform(-1, 1, 3)
            q[a + 3: a + 7] = rng.normal(size=4)
            q[a + 3: a + 7] /= np.linalg.norm(q[a + 3: a + 7])
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            q[a: a + 4] = rng.normal(size=4) / 0.5
            q[a: a + 4] /= np.linalg.norm(q[a: a + 4])
        else:
            q[a] += rng.uniform(-1, 1) * (0.3 if kind == mujoco.mjtJoint.mjJNT_SLIDE else 1.0)
    return q, rng.uniform(-speed, speed, model.nv), rng.uniform(-1, 1, model.nu)


SAME_AS = {"brax/ant": "gymnasium/ant", "brax/humanoid": "gymnasium/humanoid"}  # the same model, see below


@pytest.mark.parametrize("name", [m for m in MODELS if m not in SAME_AS])
def test_models_match_mujoco_in_free_flight(name):
    """M, bias and qacc to 1e-10 at two random states; 30 steps of semi-implicit Euler to 1e-9 (one compiled program
    per model)."""
    model, tree = free_flight(name)
    assert isinstance(tree, Tree) and (tree.nq, tree.nv, tree.m) == (model.nq, model.nv, model.nu)
    rng = np.random.default_rng(0)
    states = [random_state(model, rng) for _ in range(2)]
    q, qd, u = (np.stack(x) for x in zip(*states))
    steps = 30
    us = rng.uniform(-1, 1, (steps, model.nu))

    control = (lambda x: x) if model.nu else (lambda x: None)

    @jax.jit
    def ours(q, qd, u, us):
        terms = (lg.mass_matrix(tree, q), lg.bias_forces(tree, q, qd), lg.forward_dynamics(tree, q, qd, control(u)))
        tr = lg.simulate(tree, q[-1], qd[-1], control(us), float(model.opt.timestep), lg.SemiImplicitEuler(),
                         steps=steps)
        return terms, tr

    (M, bias, qacc), tr = ours(*(jnp.asarray(x) for x in (q, qd, u, us)))
    for k in range(2):
        for a, b in zip((M[k], bias[k], qacc[k]), mujoco_terms(model, q[k], qd[k], u[k])):
            assert rel(a, b) <= EXACT
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q[-1], qd[-1]
    for t in range(steps):
        data.ctrl[:] = us[t]
        mujoco.mj_step(model, data)
    assert rel(tr.q[-1], data.qpos) <= TRAJECTORY and rel(tr.qd[-1], data.qvel) <= TRAJECTORY
    assert tr.q.shape == (steps + 1, model.nq) and tr.qd.shape == (steps + 1, model.nv)


@pytest.mark.parametrize("name", ["gymnasium/ant", "dm_control/humanoid", "dm_control/finger", "balls",
                                  "urdf/tilted_arm"])
def test_to_mjcf_round_trips(name):
    """``to_mjcf`` writes a tree that MuJoCo compiles to the same dynamics (M, bias and qacc of the written model equal
    the original's to 1e-12 at random states: MuJoCo against MuJoCo) and that ``from_mjcf`` reads back as the same tree
    (the same bodies, joints and motors, every parameter to 1e-12)."""
    model, tree = free_flight(name)
    written = mujoco.MjModel.from_xml_string(to_mjcf(tree, timestep=float(model.opt.timestep)))
    back = from_mjcf(written, limits="ignore", contact="ignore")
    assert back.parents == tree.parents and [type(j) for j in back.joints] == [type(j) for j in tree.joints]
    assert [(m.joint, m.control_range) for m in back.motors] == [(m.joint, m.control_range) for m in tree.motors]
    assert [b.name for b in back.bodies] == [b.name for b in tree.bodies]
    for a, b in zip(tree.joints, back.joints):
        if isinstance(a, (Hinge, Slide)):
            np.testing.assert_allclose(a.axis, b.axis, rtol=0, atol=1e-15)
    for a, b in zip(jax.tree_util.tree_leaves(tree), jax.tree_util.tree_leaves(back)):
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=0, atol=1e-12)
    rng = np.random.default_rng(2)
    for _ in range(2):
        q, qd, u = random_state(model, rng)
        for a, b in zip(mujoco_terms(written, q, qd, u), mujoco_terms(model, q, qd, u)):
            assert rel(a, b) <= 1e-12


def test_to_mjcf_refuses_a_spring_rest_that_mjcf_cannot_state():
    tree = Tree([Body(1.0, (0.1, 0.1, 0.1), joints=[Ball(stiffness=2.0, springref=(0.0, 1.0, 0.0, 0.0))])])
    with pytest.raises(NotImplementedError, match="joint 0 \\(Ball\\) has a spring"):
        to_mjcf(tree)
    assert "stiffness=\"2.0\"" in to_mjcf(Tree([Body(1.0, (0.1, 0.1, 0.1), joints=[Ball(stiffness=2.0)])]))


@pytest.mark.parametrize("name", list(SAME_AS))
def test_brax_models_are_gymnasiums(name):
    """Brax's ant and humanoid compile to Gymnasium's models (MuJoCo's own terms equal at random states) and read as
    the same trees (every parameter equal), so :func:`test_models_match_mujoco_in_free_flight` on Gymnasium's checks
    them too (without compiling the same program twice)."""
    model, tree = free_flight(name)
    other, other_tree = free_flight(SAME_AS[name])
    (la, ta), (lb, tb) = (jax.tree_util.tree_flatten(t) for t in (tree, other_tree))
    assert ta == tb and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(la, lb))
    rng = np.random.default_rng(3)
    for _ in range(2):
        q, qd, u = random_state(model, rng)
        for a, b in zip(mujoco_terms(model, q, qd, u), mujoco_terms(other, q, qd, u)):
            np.testing.assert_array_equal(a, b)


def test_quaternions_stay_unit_and_are_normalised_on_entry():
    """A non-unit quaternion in q0 is normalised (MuJoCo reads it so: the same M); a zero one is refused by name."""
    model, tree = free_flight("balls")
    q, qd, _ = random_state(model, np.random.default_rng(1))
    scaled = q.copy()
    scaled[:4] *= 3.0
    tr = lg.simulate(tree, jnp.asarray(scaled), jnp.asarray(qd), jnp.zeros((50, 1)), 0.005, lg.RK4())
    for a in (0, 4, 8):  # the three balls' quaternions
        np.testing.assert_allclose(np.linalg.norm(np.asarray(tr.q)[:, a: a + 4], axis=1), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.q[0, :4], q[:4], rtol=0, atol=1e-15)
    assert rel(lg.mass_matrix(tree, jnp.asarray(scaled)), lg.mass_matrix(tree, jnp.asarray(q))) <= 1e-14
    zero = q.copy()
    zero[4:8] = 0.0
    with pytest.raises(ValueError, match=r"q0\[4:8\] is joint 1's quaternion and must not be zero"):
        lg.simulate(tree, jnp.asarray(zero), jnp.asarray(qd), jnp.zeros((2, 1)), 0.005)


def _spinning_humanoid(gravity=(0.0, 0.0, 0.0)):
    """dm_control's humanoid without damping, springs or gravity, spinning and tumbling from a random pose."""
    model = _compile(MODELS["dm_control/humanoid"])
    model.dof_damping[:] = 0.0
    model.jnt_stiffness[:] = 0.0
    model.opt.gravity[:] = gravity
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    tree = from_mjcf(model, limits="ignore", contact="ignore")
    q, qd, _ = random_state(model, np.random.default_rng(2), speed=1.0)
    return tree, jnp.asarray(q), jnp.asarray(qd)


def _rotation(quat):
    """The rotation matrices of unit quaternions ``(..., 4)`` (MuJoCo's ``mju_quat2Mat``, written out)."""
    w, x, y, z = (quat[..., i] for i in range(4))
    return jnp.stack([jnp.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                      jnp.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
                      jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1)], -2)


def test_free_floating_humanoid_conserves_momentum_and_energy():
    """No gravity, damping or spring: the exact flow conserves the energy, the linear momentum (``M qd``'s first three
    entries, the free joint's conjugate) and the angular momentum about the world's origin; each solver's errors in
    all three fall at its order (RK4 16-fold per halved step, semi-implicit Euler 2-fold)."""
    tree, q0, qd0 = _spinning_humanoid()

    def invariants(q, qd):
        p = jnp.einsum("...ij,...j->...i", lg.mass_matrix(tree, q), qd)
        L = jnp.cross(q[:, :3], p[:, :3]) + jnp.einsum("tij,tj->ti", _rotation(q[:, 3:7]), p[:, 3:6])
        return sum(lg.energy(tree, q, qd)), p[:, :3], L

    for solver, h, order in ((lg.RK4(), 0.01, 4), (lg.SemiImplicitEuler(), 0.004, 1)):
        n = int(round(0.4 / h))
        # one program for both step sizes: dt is an argument; the halved step runs the n steps twice in a row
        run = jax.jit(lambda q, qd, dt: lg.simulate(tree, q, qd, jnp.zeros((n, tree.m)), dt, solver))
        coarse = run(q0, qd0, h)
        first = run(q0, qd0, h / 2)
        second = run(first.q[-1], first.qd[-1], h / 2)
        fine_q = jnp.concatenate([first.q[::2], second.q[2::2]])
        fine_qd = jnp.concatenate([first.qd[::2], second.qd[2::2]])
        check = jax.jit(lambda q, qd: [jnp.max(jnp.abs(x - x[0])) for x in invariants(q, qd)])
        errs = np.array([check(coarse.q, coarse.qd), check(fine_q, fine_qd)], float)
        orders = np.log2(errs[0] / errs[1])
        assert np.all(np.abs(orders - order) < 0.4), (type(solver).__name__, orders, errs)


def _tumbling_body_with_arm():
    """A free body carrying a ball-jointed arm without gravity, and a tumbling start ``(tree, q0, qd0)``."""
    tree = Tree([Body(2.0, (0.1, 0.3, 0.5), (0.1, 0.05, -0.2), joints=[Free()]),
                 Body(1.0, (0.05, 0.02, 0.04), (0.0, 0.0, -0.3), joints=[Ball()], pos=(0.2, 0, 0))], gravity=(0, 0, 0))
    return (tree, jnp.array([0, 0, 0, 0.9, 0.1, 0.3, 0.2, 0.8, 0.3, -0.2, 0.1]),
            jnp.array([0.3, -0.2, 0.1, 2.0, -3.0, 1.5, 1.0, 0.5, -2.0]))


def test_rk4_is_fourth_order_on_rotations():
    """A free body carrying a ball-jointed arm, tumbling without gravity: RK4's energy error falls at order 4 (the
    stages through dexpinv; MuJoCo's scheme without it, checked here too, is second order in the rotations)."""
    tree, q0, qd0 = _tumbling_body_with_arm()
    run = jax.jit(lambda q, qd, dt, n: lg.simulate(tree, q, qd, None, dt, lg.RK4(), steps=50), static_argnums=3)
    energy = jax.jit(lambda q, qd: sum(lg.energy(tree, q, qd)))
    errs = []
    for h in (0.02, 0.01, 0.005):  # 1 s each: the 50-step program (dt an argument) run 1, 2 and 4 times in a row
        q, qd, E = q0, qd0, []
        for _ in range(int(round(1 / (50 * h)))):
            tr = run(q, qd, h, 50)
            E.append(energy(tr.q, tr.qd))
            q, qd = tr.q[-1], tr.qd[-1]
        E = jnp.concatenate(E)
        errs.append(float(jnp.max(jnp.abs(E - E[0]))))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 3.8) & (orders < 4.3)), orders


def test_adaptive_steps_follow_the_flow_of_a_tumbling_tree():
    """The free body and its ball-jointed arm of the test above, 1 s through diffrax's adaptive Tsit5 (``dq/dt`` of the
    quaternions in R^nq, renormalised after each interval): the quaternions stay unit, the energy is conserved and
    the final state is RK4's at a step 200 times finer than its own first guess, both to the tolerance's scale
    (measured: 1e-11 relative in the energy, 2e-10 in the state; at rtol = atol = 1e-6 the state is 3e-7 off)."""
    tree, q0, qd0 = _tumbling_body_with_arm()
    adaptive = jax.jit(lambda q, qd: lg.simulate(tree, q, qd, None, 0.1, lg.Tsit5(), steps=10, rtol=1e-10, atol=1e-10))(
        q0, qd0)
    fine = jax.jit(lambda q, qd: lg.simulate(tree, q, qd, None, 0.1, lg.RK4(), steps=10, substeps=200))(q0, qd0)
    quats = np.asarray(adaptive.q)[:, [3, 4, 5, 6, 7, 8, 9, 10]].reshape(-1, 2, 4)
    np.testing.assert_allclose(np.linalg.norm(quats, axis=-1), 1.0, atol=1e-14)
    energy = np.asarray(jax.jit(lambda q, qd: sum(lg.energy(tree, q, qd)))(adaptive.q, adaptive.qd))
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * abs(energy[0]), energy - energy[0]  # measured 1e-11
    np.testing.assert_allclose(np.asarray(adaptive.q[-1]), np.asarray(fine.q[-1]), atol=1e-8)
    np.testing.assert_allclose(np.asarray(adaptive.qd[-1]), np.asarray(fine.qd[-1]), atol=1e-8)


def test_gradients_from_rest_are_finite_and_exact():
    """d(final state)/d(initial velocities) of 40 steps from rest (every angular velocity exactly 0, where Brax's and
    jaxsim's quaternion gradients turned NaN): reverse mode equals forward mode to round-off (1e-10), and central
    differences to 1e-6. The chain's tiny last body makes M ill-conditioned, so its states carry round-off ~1e-11:
    measured, the differences' error falls with h down to h = 1e-4 (9e-8) and grows below it like 1e-11 / h (5e-6 at
    h = 1e-6), so h = 1e-4."""
    model, tree = free_flight("balls")
    q, _, _ = random_state(model, np.random.default_rng(4))
    q = jnp.asarray(q)

    def final(qd0):
        tr = lg.simulate(tree, q, qd0, jnp.zeros((40, 1)), 0.005, lg.SemiImplicitEuler(), check=False)
        return jnp.concatenate([tr.q[-1], tr.qd[-1]])

    rest = jnp.zeros(tree.nv)
    J, Jf = jax.jit(jax.jacrev(final))(rest), jax.jit(jax.jacfwd(final))(rest)
    assert np.all(np.isfinite(J)) and np.max(np.abs(J)) > 0.01 and rel(J, Jf) <= 1e-10
    h = 1e-4
    steps = jnp.asarray(np.eye(tree.nv) * h)
    fd = np.asarray(jax.jit(jax.vmap(final))(jnp.concatenate([steps, -steps])))
    assert rel(J, (fd[: tree.nv] - fd[tree.nv:]).T / (2 * h)) <= 1e-6
    # and through the exponential map itself, at exactly zero rotation
    g = jax.grad(lambda w: jnp.sum(lg.rbda.integrate_positions(tree, q, w, 0.01) ** 2))(rest)
    assert np.all(np.isfinite(g))


def test_a_float32_tree_computes_in_float32_under_64_bit_mode():
    """A tree cast to float32 stays float32 with JAX's 64-bit mode on (as here): the static constants (joint axes,
    anchors, the 0/1 link matrices, armature, damping and stiffness) follow the coordinates' dtype instead of promoting
    them, so ``lg.simulate`` runs (its scan once failed on a float64 carry) and so does its gradient. The tree has
    every joint kind (a free base; a tilted hinge with a spring, a limit and a clamped motor; a slide; a sprung,
    damped ball with armature) and a foot pressed into the ground. Its 40 semi-implicit Euler steps meet float64's to
    float32 round-off grown over the steps: measured 3.6e-7 of the largest entry; 40 steps x float32's 1.2e-7 bound it
    by 5e-6."""
    tree = Tree([
        Body(3.0, (0.1, 0.2, 0.15), (0.0, 0.0, 0.1), joints=[Free(damping=0.1)], contacts=[(0.1, 0.1, -0.1, 0.05)]),
        Body(1.0, (0.02, 0.03, 0.01), (0.0, 0.05, -0.1),
             joints=[Hinge((1, 1, 0), (0.0, 0.0, 0.05), armature=0.02, stiffness=3.0, range=(-0.3, 0.3)),
                     Slide((0, 0, 1), damping=0.5)], pos=(0.2, 0.0, 0.0), quat=(0.9, 0.0, 0.2, 0.1),
             contacts=[(0.0, 0.0, -0.2, 0.03)]),
        Body(0.5, (0.01, 0.01, 0.01), (0.0, 0.0, -0.1), joints=[Ball(damping=0.3, armature=0.01, stiffness=2.0)],
             parent=0, pos=(-0.2, 0.0, 0.0)),
    ], motors=[Motor(1, gear=2.0, control_range=(-1.0, 1.0))], contact=lg.PenaltyContact(2e4, 5e3, 1e3, 0.75),
        limits=lg.PenaltyLimits(1e3, 10.0))
    rng = np.random.default_rng(1)
    q = np.concatenate([[0.0, 0.0, 0.12, 1.0, 0.0, 0.0, 0.0], [0.2, 0.05], [0.9, 0.1, 0.3, 0.2] / np.sqrt(0.95)])
    qd, us = rng.normal(size=tree.nv), rng.uniform(-1.5, 1.5, (40, tree.m))

    def run(tree, qd0, dtype):
        return lg.simulate(tree, jnp.asarray(q, dtype), qd0, jnp.asarray(us, dtype), 0.002, lg.SemiImplicitEuler())

    def final(qd0):
        tr = run(lg.astype(tree, jnp.float32), qd0, jnp.float32)
        return jnp.sum(tr.q[-1] ** 2), tr

    exact = run(tree, jnp.asarray(qd), jnp.float64)
    (_, low), g = jax.value_and_grad(final, has_aux=True)(jnp.asarray(qd, jnp.float32))
    assert low.q.dtype == low.qd.dtype == g.dtype == jnp.float32
    assert rel(low.q, exact.q) <= 5e-6 and rel(low.qd, exact.qd) <= 5e-6
    assert np.all(np.isfinite(g)) and np.max(np.abs(g)) > 0


HAND_WRITTEN = """<mujoco><worldbody><body><joint type="free" damping="0.1"/>
  <inertial pos="0 0 0.1" mass="3" diaginertia="0.1 0.2 0.15"/>
  <body pos="0.2 0 0" quat="0.9 0 0.2 0.1"><joint name="h" axis="1 1 0" pos="0 0 0.05" armature="0.02"/>
    <joint type="slide" axis="0 0 1" damping="0.5"/><inertial pos="0 0.05 -0.1" mass="1" diaginertia="0.02 0.03 0.01"/>
  </body></body></worldbody><actuator><motor joint="h" gear="2" ctrlrange="-1 1" ctrllimited="true"/></actuator>
</mujoco>"""


def test_a_tree_built_by_hand_equals_mujoco_on_its_mjcf():
    """Bodies, joints and a motor written in Python give MuJoCo's dynamics of the same model written in MJCF (a free
    body carrying a body on a tilted hinge with an anchor, then a slide; a clamped motor)."""
    tree = Tree([
        Body(3.0, (0.1, 0.2, 0.15), (0.0, 0.0, 0.1), joints=[Free(damping=0.1)]),
        Body(1.0, (0.02, 0.03, 0.01), (0.0, 0.05, -0.1), joints=[Hinge((1, 1, 0), (0.0, 0.0, 0.05), armature=0.02),
                                                                 Slide((0, 0, 1), damping=0.5)],
             pos=(0.2, 0.0, 0.0), quat=(0.9, 0.0, 0.2, 0.1)),
    ], motors=[Motor(1, gear=2.0, control_range=(-1.0, 1.0))])
    model = mujoco.MjModel.from_xml_string(HAND_WRITTEN)
    rng = np.random.default_rng(5)
    for u in (0.4, 3.0):  # 3 is clamped to 1
        q, qd, _ = random_state(model, rng)
        M, bias, qacc = mujoco_terms(model, q, qd, [u])
        x = (jnp.asarray(q), jnp.asarray(qd))
        assert rel(lg.mass_matrix(tree, x[0]), M) <= EXACT and rel(lg.bias_forces(tree, *x), bias) <= EXACT
        qdd = lg.forward_dynamics(tree, *x, jnp.array([u]))
        assert rel(qdd, qacc) <= EXACT
        assert rel(lg.inverse_dynamics(tree, *x, qdd), jnp.zeros(8).at[6].set(2.0 * min(u, 1.0))) <= 1e-12


def test_bad_input_is_refused_by_name():
    with pytest.raises(ValueError, match=r"Hinge\.axis must not be zero"):
        Hinge((0, 0, 0))
    with pytest.raises(TypeError, match=r"Body\.joints\[0\] must be a joint of lagrange\.joints"):
        Body(1.0, joints=["ball"])
    with pytest.raises(ValueError, match=r"Body.mass must be >= 0"):
        Body(-1.0)
    with pytest.raises(ValueError, match=r"Body 'b'\.inertia must be positive semi-definite"):
        Body(1.0, ((1, 0, 0), (0, -1, 0), (0, 0, 1)), name="b")
    with pytest.raises(ValueError, match=r"a free body must hang from the world"):
        Tree([Body(1.0, (1, 1, 1), joints=[Hinge()]), Body(1.0, (1, 1, 1), joints=[Free()])])
    with pytest.raises(ValueError, match=r"Tree.motors\[0\] drives joint 0, a Ball: a motor drives a Hinge or a Slide"):
        Tree([Body(1.0, (1, 1, 1), joints=[Ball()])], motors=[Motor(0)])
    tree = Tree([Body(1.0, (1, 1, 1), joints=[Ball()])])
    with pytest.raises(ValueError, match=r"q must have shape \(\.\.\., 4\)"):
        lg.mass_matrix(tree, jnp.zeros(3))
    with pytest.raises(NotImplementedError, match="MomentumEuler runs on planar trees only"):
        lg.simulate(tree, jnp.array([1.0, 0, 0, 0]), jnp.zeros(3), None, 0.01, lg.MomentumEuler(), steps=2)


@pytest.mark.parametrize("extra, error, match", [
    ('<tendon><fixed name="t" stiffness="10"><joint joint="j" coef="1"/></fixed></tendon>', NotImplementedError,
     "tendon 't' carries force"),
    ('<equality><joint joint1="j" joint2="k"/></equality>', NotImplementedError, "equality constraint"),
    ('<actuator><motor name="m" joint="b"/></actuator>', NotImplementedError,
     "actuator 'm' drives joint 'b', a ball or free joint"),
])
def test_what_a_tree_cannot_reproduce_is_refused(extra, error, match):
    xml = f"""<mujoco><worldbody><body><joint name="b" type="ball"/><geom size="0.1" contype="0" conaffinity="0"/>
    <body pos="0 0 -0.3"><joint name="j" axis="0 1 0"/><joint name="k" axis="1 0 0"/>
    <geom size="0.1" contype="0" conaffinity="0"/></body></body></worldbody>{extra}</mujoco>"""
    with pytest.raises(error, match=match):
        from_mjcf(xml, limits="ignore", contact="ignore")


def test_a_tendon_that_only_limits_is_dropped_with_limits_ignore():
    """Gymnasium's humanoid's hip-knee tendons carry a limit only: refused by default, dropped with limits="ignore"."""
    with pytest.raises(ValueError, match="is limited"):
        from_mjcf(MODELS["gymnasium/humanoid"], contact="ignore")
    assert isinstance(from_mjcf(MODELS["gymnasium/humanoid"], limits="ignore", contact="ignore"), Tree)
    ant = from_mjcf(MODELS["gymnasium/ant"], limits="ignore", contact=lg.PenaltyContact(1e4, 1e3, 1e3, 0.9))
    assert ant.contact is not None and ant.limits is None  # 3-D contact: tests/lagrange/rbda/test_contact.py
    with pytest.raises(NotImplementedError, match="contact law"):
        to_mjcf(ant)
