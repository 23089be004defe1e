"""Muscles (:class:`lagrange.Muscle`): path lengths and generalized forces against MuJoCo's spatial tendons through
sites (an independent computation of ``L`` and its moment arms), against central differences of ``L``, the power
balance of a muscle-driven tree, and bad input."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange import rbda
from lagrange.interop.mjcf import to_mjcf
from tests.helpers import rel

TIGHT = 1e-12  # float64 round-off of a few bodies' kinematics


def _arm(**kw):
    """A 3-D arm: a ball at the shoulder, two hinges about tilted axes, a body welded to the hand, a motor on the
    elbow; two muscles across it (one within a body on part of its way, one onto the welded body)."""
    bodies = [lg.Body(1.0, (0.01, 0.02, 0.03), (0, 0, -0.2), joints=[lg.Ball(damping=kw.get("damping", 0.1))],
                      pos=(0, 0, 1), name="upper"),
              lg.Body(0.5, (0.01, 0.01, 0.005), (0.1, 0, 0), joints=[lg.Hinge((0, 1, 0))], parent=0,
                      pos=(0, 0, -0.4), name="fore"),
              lg.Body(0.2, (0.001, 0.001, 0.001), (0, 0, 0.05), joints=[lg.Hinge((1, 0, 0.3))], parent=1,
                      pos=(0.3, 0, 0), quat=(0.9, 0.1, 0.2, 0.3), name="hand"),
              lg.Body(0.1, (1e-4, 1e-4, 1e-4), (0, 0, 0), parent=2, pos=(0.05, 0.0, 0.02), name="finger")]
    muscles = [lg.Muscle([(0, (0.05, 0, -0.1)), (1, (0.05, 0.01, 0.05)), (2, (0.0, 0.02, 0.03))], 100.0, name="flexor"),
               lg.Muscle([(0, (0, 0.05, -0.35)), (0, (0, 0.06, -0.38)), (1, (0.1, 0.03, 0.0)), (1, (0.2, 0.0, 0.0)),
                          (3, (0.01, 0, 0))], 50.0, name="extensor")]
    return lg.Tree(bodies, motors=[lg.Motor(1, 2.0)], muscles=muscles, gravity=kw.get("gravity", (0, 0, -9.81)))


def _state(rng, tree):
    q = np.concatenate([rng.normal(size=4), rng.uniform(-1.5, 1.5, 2)])
    q[:4] /= np.linalg.norm(q[:4])
    return q, rng.uniform(-1, 1, tree.nv)


def test_lengths_forces_and_accelerations_equal_mujocos_tendons():
    """``L`` is MuJoCo's ``ten_length``, the muscles' and the motor's forces its ``qfrc_actuator`` (a tendon
    actuator of gain ``-strength``, activations clamped into [0, 1] by its ``ctrlrange``) and ``qdd`` its ``qacc``."""
    import mujoco

    tree = _arm()
    model = mujoco.MjModel.from_xml_string(to_mjcf(tree))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for _ in range(4):
        q, qd = _state(rng, tree)
        u = rng.uniform(-0.3, 1.3, tree.m)  # some activations outside [0, 1]: clamped
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, qd, u
        mujoco.mj_forward(model, data)
        q_, qd_, u_ = (jnp.asarray(x) for x in (q, qd, u))
        assert rel(lg.muscle_lengths(tree, q_), data.ten_length) <= TIGHT
        motor = np.zeros(tree.nv)
        motor[3] = 2.0 * u[0]
        assert rel(rbda.muscle_torques(tree, q_, qd_, u_) + motor, data.qfrc_actuator) <= TIGHT
        assert rel(lg.forward_dynamics(tree, q_, qd_, u_), data.qacc) <= 1e-10  # qacc ~ 1e3 on the light hand


def test_the_force_is_minus_tension_times_the_gradient_of_the_length():
    """``tau = -F dL/dq`` against central differences of ``L`` along each velocity (``q`` moved on its manifold), and
    against ``jax.jacfwd`` of ``L``; a segment within one body (the extensor's first) pulls nothing."""
    tree = _arm()
    rng = np.random.default_rng(1)
    q, qd = (jnp.asarray(x) for x in _state(rng, tree))
    u = jnp.asarray([0.0, 0.7, 0.4])

    @jax.jit
    def L(d):
        return lg.muscle_lengths(tree, rbda.integrate_positions(tree, q, d, 1.0))

    h = 1e-6
    J_fd = np.stack([(L(h * e) - L(-h * e)) / (2 * h) for e in np.eye(tree.nv)], axis=-1)  # (muscles, nv)
    F = np.array([0.7 * 100.0, 0.4 * 50.0])
    tau = np.asarray(rbda.muscle_torques(tree, q, qd, u))
    assert np.max(np.abs(tau + F @ J_fd)) <= 1e-7 * np.max(np.abs(tau))  # central differences: O(h^2) + round-off
    assert rel(tau, -F @ np.asarray(jax.jacfwd(L)(jnp.zeros(tree.nv)))) <= TIGHT
    assert np.max(np.abs(tau[:3])) <= 1e-12 * np.max(np.abs(tau))  # the root ball turns every waypoint alike


def test_a_muscle_driven_tree_changes_its_energy_by_the_muscles_work():
    """Without damping, a muscle of constant tension ``F`` does the work ``-F (L(T) - L(0))``: the energy changes by
    exactly that, up to RK4's error (measured 1.0e-10, 1.8e-12 and 3.7e-13 of the work at 1, 2 and 4 substeps)."""
    tree = _arm(damping=0.0)
    rng = np.random.default_rng(2)
    q0, qd0 = (jnp.asarray(x) for x in _state(rng, tree))
    u = jnp.asarray([0.0, 0.6, 0.9])
    traj = lg.simulate(tree, q0, qd0, jnp.tile(u, (200, 1)), 1e-3, lg.RK4(), substeps=2)
    E = [sum(lg.energy(tree, traj.q[i], traj.qd[i])) for i in (0, -1)]
    L = [lg.muscle_lengths(tree, traj.q[i]) for i in (0, -1)]
    work = -float(jnp.sum(jnp.asarray([0.6 * 100.0, 0.9 * 50.0]) * (L[1] - L[0])))
    assert abs(work) > 0.1  # the muscles move the arm
    assert abs(float(E[1] - E[0]) - work) <= 1e-10 * abs(work)


def test_a_rollouts_gradient_with_respect_to_the_activations_is_central_differences():
    tree = _arm()
    q0, qd0 = (jnp.asarray(x) for x in _state(np.random.default_rng(3), tree))
    us = jnp.tile(jnp.asarray([0.1, 0.5, 0.5]), (20, 1))

    @jax.jit
    def final(us):
        return lg.simulate(tree, q0, qd0, us, 0.005, lg.SemiImplicitEuler(), 2).q[-1, 4]

    e = jnp.zeros(us.shape).at[:, 1].set(1.0).at[:10, 2].set(-0.5)
    _, slope = jax.jvp(final, (us,), (e,))
    fd = (final(us + 1e-6 * e) - final(us - 1e-6 * e)) / 2e-6
    assert abs(float(fd)) > 1e-3
    assert abs(float(slope) - float(fd)) <= 1e-6 * abs(float(fd))


def test_activations_are_clamped_and_bad_muscles_are_refused_by_name():
    tree = _arm()
    q, qd = (jnp.asarray(x) for x in _state(np.random.default_rng(4), tree))
    tau = lambda a: rbda.muscle_torques(tree, q, qd, jnp.asarray([0.0, *a]))  # noqa: E731
    assert np.array_equal(tau([1.5, 1.0]), tau([1.0, 1.0])) and not np.any(tau([-0.5, 0.0]))
    assert tree.m == 3 and tree.muscle_index("extensor") == 1
    with pytest.raises(KeyError, match=r"no muscle named 'biceps'; its muscles: \['flexor', 'extensor'\]"):
        tree.muscle_index("biceps")
    with pytest.raises(ValueError, match=r"Muscle 'm'.path has 1 waypoint; a path needs at least two"):
        lg.Muscle([(0, (0, 0, 0))], 1.0, name="m")
    with pytest.raises(ValueError, match=r"Muscle 'm'.strength must be >= 0, got -1.0"):
        lg.Muscle([(0, (0, 0, 0)), (1, (0, 0, 1))], -1.0, name="m")
    with pytest.raises(ValueError, match=r"Muscle.path\[1\]'s body must be a body's index >= 0, got -1"):
        lg.Muscle([(0, (0, 0, 0)), (-1, (0, 0, 1))], 1.0)
    with pytest.raises(TypeError, match=r"Muscle.path's points must be three numbers each"):
        lg.Muscle([(0, (0, 0, 0)), (1, "up")], 1.0)
    with pytest.raises(ValueError, match=r"Tree.muscles\[0\] \('far'\) has a waypoint on body 7; the tree has bodies "
                                         r"0..3"):
        lg.Tree(tree.bodies, muscles=[lg.Muscle([(0, (0, 0, 0)), (7, (0, 0, 1))], 1.0, name="far")])
    with pytest.raises(ValueError, match=r"actuation_matrix: the tree has muscles"):
        lg.actuation_matrix(tree)


def test_a_planar_tree_with_muscles_runs_on_the_general_algorithms():
    """The planar backends carry motors only: a planar chain with a muscle is solved by the general algorithms, and
    the muscle's force is ``-F dL/dq`` there too."""
    chain = lg.systems.n_link_pendulum(2)
    tree = lg.Tree(chain.bodies, chain.gravity, muscles=[lg.Muscle([(0, (0.0, 0, -0.3)), (1, (0.0, 0, -0.5))], 10.0)])
    assert tree.planar
    q, qd, u = jnp.asarray([0.3, 0.8]), jnp.asarray([0.1, -0.2]), jnp.asarray([1.0])
    forced = lg.forward_dynamics(tree, q, qd, u) - lg.forward_dynamics(tree, q, qd, jnp.zeros(1))
    J = jax.jacfwd(lambda x: lg.muscle_lengths(tree, x))(q)
    assert rel(lg.mass_matrix(tree, q) @ forced, -10.0 * J[0]) <= TIGHT


def test_a_length_dependent_law_is_a_subclass_that_reads_the_length():
    """A Hill-type law is a subclass: its ``tension`` reads ``L`` (``length_dependent``), muscles of two classes mix in
    one tree, and each pulls with its own law's ``-F(L) dL/dq``."""

    class Scaled(lg.Muscle):
        length_dependent = True

        def tension(self, activation, length, velocity):
            return activation * self.strength * (1.0 - (length - 0.3) ** 2)

    tree = _arm()
    first = tree.muscles[0]
    mixed = lg.Tree(tree.bodies, motors=tree.motors, muscles=[Scaled(list(zip(first.bodies, first.points)), 100.0),
                                                               tree.muscles[1]])
    q, qd = (jnp.asarray(x) for x in _state(np.random.default_rng(5), tree))
    u = jnp.asarray([0.0, 0.6, 0.4])
    L = np.asarray(lg.muscle_lengths(mixed, q))
    J = np.asarray(jax.jacfwd(lambda d: lg.muscle_lengths(mixed, rbda.integrate_positions(mixed, q, d, 1.0)))(
        jnp.zeros(mixed.nv)))
    F = np.array([0.6 * 100.0 * (1.0 - (L[0] - 0.3) ** 2), 0.4 * 50.0])
    assert rel(rbda.muscle_torques(mixed, q, qd, u), -F @ J) <= TIGHT
