"""The SHAC authors' cartpole (lagrange/tasks/diffrl_cartpole.py): its parameters, reward and observation by hand, its
reset distribution, its dynamics from rest against the closed-form 2x2 solve, action clipping and field checks."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.tasks import POLE_INERTIA, DiffRLCartpole, TaskState, balanced, upright_error


def test_diffrl_cartpole_physics_and_readings():
    task = DiffRLCartpole.diffrl()
    c = task.chain
    np.testing.assert_allclose(np.asarray(c.mass), [50.0, 2.5])
    np.testing.assert_allclose(np.asarray(c.gear), [1000.0])
    np.testing.assert_allclose(POLE_INERTIA, 2.5 * (1 + 0.05**2) / 12)
    assert (task.dt, task.horizon, task.observation_size, task.action_size) == (1 / 60, 240, 5, 1)
    assert (task.cart, task.first_pole, task.n_links, task.substeps, task.name) == (True, 1, 1, 1, "diffrl_cartpole")
    assert isinstance(task.solver, lg.RK4) and (task.noise_q, task.noise_qd) == (math.pi / 2, 0.25)
    # Upright pole at rest, cart at 0: reward 0 (the maximum); observation (x, dx, sin th, cos th, dth).
    up = TaskState(jnp.array([0.0, jnp.pi]), jnp.zeros(2))
    assert float(task.reward(up, jnp.zeros(1), up)) == 0.0
    # "balanced" reads the pole after the cart (the SHAC example evaluates with it)
    traj = jnp.stack([up.q, up.q.at[1].add(0.1), up.q.at[1].add(0.3)])
    assert bool(balanced(task, traj[:2])) and not bool(balanced(task, traj))
    np.testing.assert_allclose(upright_error(task, traj), [0.0, 0.1, 0.3], atol=1e-6)
    np.testing.assert_allclose(task.observe(up), [0, 0, 0, 1, 0], atol=1e-15)
    # The authors' weights, by hand: th = q - pi wrapped.
    s = TaskState(jnp.array([0.3, 0.5]), jnp.array([-0.7, 2.0]))
    th = 0.5 - math.pi
    want = -(th**2 + 0.1 * 2.0**2 + 0.05 * 0.3**2 + 0.1 * 0.7**2)
    np.testing.assert_allclose(float(task.reward(s, jnp.zeros(1), s)), want, rtol=1e-14)
    np.testing.assert_allclose(task.observe(s), [0.3, -0.7, math.sin(th), math.cos(th), 2.0], rtol=1e-14)
    # the pole's readings: wrapped angle, absolute orientation (one link: the same), velocity
    np.testing.assert_allclose(task.angles(s), [th], rtol=1e-14)  # th = 0.5 - pi is in (-pi, pi]
    np.testing.assert_allclose(task.link_angles(s), [th], rtol=1e-14)
    back = TaskState(jnp.array([0.0, -1.0]), jnp.zeros(2))  # -1 - pi wraps to pi - 1
    np.testing.assert_allclose(task.angles(back), [math.pi - 1.0], rtol=1e-14)
    np.testing.assert_allclose(task.link_angles(back), [math.pi - 1.0], rtol=1e-14)
    np.testing.assert_array_equal(task.angular_velocities(s), [2.0])
    # Reset: hanging down with U(-pi/2, pi/2) on x, q and U(-0.25, 0.25) on velocities.
    states = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 4000))
    q, qd = np.asarray(states.q), np.asarray(states.qd)
    assert np.abs(q).max() <= math.pi / 2 and np.abs(q).max() > 0.99 * math.pi / 2
    assert np.abs(qd).max() <= 0.25 and np.abs(qd).max() > 0.99 * 0.25
    # Dynamics, closed form: from rest hanging down, a cart force F gives
    # [[M + m, m c], [m c, I + m c^2]] (xdd, qdd) = (F, 0) with c = 0.5 m (sign of qdd aside).
    M, m, cc, inertia, F = 50.0, 2.5, 0.5, POLE_INERTIA, 1000.0
    det = (M + m) * (inertia + m * cc**2) - (m * cc) ** 2
    rest = TaskState(jnp.zeros(2), jnp.zeros(2))
    qdd = lg.forward_dynamics(c, rest.q, rest.qd, jnp.array([1.0]))
    np.testing.assert_allclose(float(qdd[0]), F * (inertia + m * cc**2) / det, rtol=1e-13)
    np.testing.assert_allclose(abs(float(qdd[1])), F * m * cc / det, rtol=1e-13)
    # Actions are clipped to [-1, 1] before the gear.
    a1, a2 = task.step(rest, jnp.array([3.0])), task.step(rest, jnp.array([1.0]))
    np.testing.assert_array_equal(np.asarray(a1.q), np.asarray(a2.q))


def test_diffrl_cartpole_reset_draws_by_hand():
    """The reset's draws, written out: ``split(key)`` into the noise on (x, q) and on (dx, dq)."""
    task = DiffRLCartpole.diffrl(noise_q=0.3, noise_qd=0.1)
    for seed in range(10):
        key = jax.random.PRNGKey(seed)
        kq, kv = jax.random.split(key)
        s = task.reset(key)
        np.testing.assert_array_equal(s.q, jax.random.uniform(kq, (2,), jnp.float64, -0.3, 0.3))
        np.testing.assert_array_equal(s.qd, jax.random.uniform(kv, (2,), jnp.float64, -0.1, 0.1))


def test_diffrl_cartpole_rejects_bad_fields():
    with pytest.raises(ValueError, match="horizon"):
        DiffRLCartpole.diffrl(horizon=0)
    with pytest.raises(ValueError, match="noise_q"):
        DiffRLCartpole.diffrl(noise_q=-1.0)
    for field, value in (("horizon", 1.5), ("substeps", 0), ("dt", -0.1), ("noise_qd", -0.1)):
        with pytest.raises(ValueError, match=f"DiffRLCartpole.{field} must be"):
            DiffRLCartpole.diffrl(**{field: value})
    with pytest.raises(ValueError, match="DiffRLCartpole.horizon must be"):
        dataclasses.replace(DiffRLCartpole.diffrl(), horizon=0)
    with pytest.raises(ValueError, match=r"DiffRLCartpole.chain must have the joints \('prismatic', 'revolute'\)"):
        DiffRLCartpole(lg.systems.acrobot())
