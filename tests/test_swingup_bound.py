"""``benchmarks/swingup_bound.py``: its rollout and its optimiser, on horizons a CI run affords."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks import swingup_bound as sb
from lagrange import tasks


def test_zero_action_keeps_the_acrobot_hanging_and_earns_10_minus_pi_squared():
    task = tasks.acrobot()
    ret, th, dth = sb.swing(task, jnp.zeros(100))
    # From rest at the bottom with no torque nothing moves: th = (pi, 0) at every step.
    np.testing.assert_allclose(np.abs(np.asarray(th)), [np.pi, 0.0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(dth), 0.0, atol=1e-6)
    np.testing.assert_allclose(float(ret), 100 * (10 - np.pi**2), rtol=1e-5)


def test_double_cartpole_pose_has_the_cart_first():
    task = tasks.double_cartpole()
    ret, pose, speeds = sb.swing(task, jnp.zeros(50))
    # cart at rest at x = 0, both poles hanging: pose (x, th1, th2) = (0, pi, 0); reward 10 - pi^2 per step
    np.testing.assert_allclose(np.abs(np.asarray(pose)), [0.0, np.pi, 0.0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(speeds), 0.0, atol=1e-6)
    np.testing.assert_allclose(float(ret), 50 * (10 - np.pi**2), rtol=1e-5)
    # full force for 10 steps: the cart leaves x = 0 and its position enters the pose
    _, pose, _ = sb.swing(task, jnp.full(10, 5.0))
    assert float(pose[0]) > 0.1


def test_optimiser_lowers_the_loss_it_minimises():
    task = tasks.acrobot()
    key = jax.random.PRNGKey(0)
    T, weight = 60, 300.0

    z0 = jax.random.normal(key, (4, T))  # the optimiser's own initial draw for this key
    z = sb.optimise_swing(task, T, starts=4, steps=60, weight=weight, key=key)
    loss = jax.vmap(lambda zz: sb.swing_loss(task, zz, weight))
    before, after = loss(z0), loss(z)
    assert np.all(np.asarray(after) < np.asarray(before)), (before, after)
