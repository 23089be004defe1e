"""``optim.identify``: a chain's parameters recovered from trajectories of the chain itself (exact data, float64), and
its argument checks; a fit whose line search meets parameters the chain cannot be simulated with carries on (it once
aborted with "reduce dt"), and one stopped by a run-time check of the parameters returns the best theta found and says
where and why."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from optim.identify import identify


def _acrobot(theta):
    """An actuated double pendulum with link masses exp(theta[:2]) and joint damping exp(theta[2:])."""
    m, b = jnp.exp(theta[:2]), jnp.exp(theta[2:])
    return Chain([Link("revolute", m[0], 1.0, damping=b[0], gear=2.0), Link("revolute", m[1], 0.8, damping=b[1])])


def _rollouts(chain, q0, qd0, controls, dt, solver=lg.SemiImplicitEuler()):
    """``lg.simulate`` from each of the starts under its controls, all in one compiled program: ``(windows, T + 1,
    nq + nv)`` states."""
    tr = jax.jit(jax.vmap(lambda *x: lg.simulate(chain, *x, dt, solver)))(jnp.asarray(q0), jnp.asarray(qd0),
                                                                          jnp.asarray(controls))
    return np.concatenate([tr.q, tr.qd], axis=-1)


def _windows(chain, rng, count=24, steps=6, dt=0.01, solver=lg.SemiImplicitEuler()):
    q0s, qd0s, controls = [], [], []
    for _ in range(count):
        q0, qd0, u = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-3, 3, 2), np.full((steps, 1), rng.uniform(-1, 1))
        q0s.append(q0)
        qd0s.append(qd0)
        controls.append(u)
    return _rollouts(chain, q0s, qd0s, controls, dt, solver), np.array(controls)


def test_recovers_masses_and_damping():
    truth = np.log([1.3, 0.7, 0.05, 0.2])
    states, controls = _windows(_acrobot(jnp.asarray(truth)), np.random.default_rng(0))
    start = np.log([2.6, 1.4, 0.3, 0.3])
    fit = identify(_acrobot, start, states, controls, 0.01, lg.SemiImplicitEuler(), iterations=60)
    assert fit.losses.shape == (61,) and float(fit.losses[-1]) < 1e-20 < float(fit.losses[0])
    np.testing.assert_allclose(np.exp(fit.theta), np.exp(truth), rtol=1e-8)
    np.testing.assert_allclose(fit.chain.mass, [1.3, 0.7], rtol=1e-8)


def _arm3d(theta):
    """A 3-D arm: a torso on a ball joint (its quaternion in ``q``) carrying a forearm on a hinge about a tilted axis,
    with masses ``exp(theta[:2])`` and the ball's damping ``exp(theta[2])``: not planar, the general algorithms."""
    m, b = jnp.exp(theta[:2]), jnp.exp(theta[2])
    return lg.Tree([lg.Body(m[0], (0.02, 0.03, 0.01), (0.0, 0.0, -0.2), joints=[lg.Ball(damping=b)]),
                    lg.Body(m[1], (0.01, 0.01, 0.002), (0.0, 0.0, -0.15), joints=[lg.Hinge((0.3, 1.0, 0.0))],
                            pos=(0.0, 0.05, -0.4))], motors=[lg.Motor(1, gear=0.5)])


def test_recovers_a_3d_trees_masses_and_damping():
    """The same fit on a 3-D tree (a ball joint's quaternion among the coordinates, ``nq = 5``, ``nv = 4``)."""
    truth = np.log([1.3, 0.7, 0.05])
    tree = _arm3d(jnp.asarray(truth))
    assert not tree.planar and (tree.nq, tree.nv) == (5, 4)
    rng = np.random.default_rng(3)
    turn = [np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * axis / np.linalg.norm(axis)])
            for a, axis in zip(rng.uniform(-1, 1, 16), rng.normal(size=(16, 3)))]
    q0 = np.stack([np.concatenate([t, rng.uniform(-1, 1, 1)]) for t in turn])
    qd0, controls = rng.uniform(-2, 2, (16, 4)), np.repeat(rng.uniform(-1, 1, (16, 1, 1)), 6, axis=1)
    states = _rollouts(tree, q0, qd0, controls, 0.01)
    fit = identify(_arm3d, np.log([2.0, 1.2, 0.2]), states, controls, 0.01, lg.SemiImplicitEuler(), iterations=60)
    assert float(fit.losses[-1]) < 1e-20 < float(fit.losses[0])
    np.testing.assert_allclose(np.exp(fit.theta), np.exp(truth), rtol=1e-8)


def test_argument_checks():
    states, controls = _windows(_acrobot(jnp.zeros(4)), np.random.default_rng(1), count=2, steps=3)
    with pytest.raises(ValueError, match=r"states must have shape \(windows, T \+ 1 >= 2, nq \+ nv = 4\)"):
        identify(_acrobot, jnp.zeros(4), states[..., :3], controls, 0.01)
    with pytest.raises(ValueError, match=r"controls must have shape \(windows, T, m\) = \(2, 3, 1\)"):
        identify(_acrobot, jnp.zeros(4), states, None, 0.01)
    with pytest.raises(ValueError, match=r"dt must be a number > 0 seconds, got 0\.0"):
        identify(_acrobot, jnp.zeros(4), states, controls, 0.0)
    with pytest.raises(ValueError, match="iterations must be an integer >= 1"):
        identify(_acrobot, jnp.zeros(4), states, controls, 0.01, iterations=0)
    with pytest.raises(ValueError, match=r"dt must be a number > 0 seconds, got 'fast'"):
        identify(_acrobot, jnp.zeros(4), states, controls, "fast")
    with pytest.raises(ValueError, match=r"states must be finite; the data hold a NaN or an infinity at \[1, 2, 0\]"):
        identify(_acrobot, jnp.zeros(4), states.copy() + np.where(np.arange(states.size).reshape(states.shape)
                                                                  == (1 * 4 + 2) * 4, np.nan, 0), controls, 0.01)
    with pytest.raises(TypeError, match=r"make_chain\(theta\) must return a lagrange\.Tree \(a lagrange\.chain\.Chain "
                                        r"is one\), got tuple"):
        identify(lambda th: (_acrobot(th),), jnp.zeros(4), states, controls, 0.01)


def _pendulum_windows(damping, count=4, steps=5):
    rng = np.random.default_rng(0)
    chain = Chain([Link("revolute", 1.0, 1.0, damping=damping, gear=1.0)])
    q0s, qd0s, controls = [], [], []
    for _ in range(count):
        u = np.full((steps, 1), rng.uniform(-1, 1))
        q0s.append(rng.uniform(-1, 1, 1))
        qd0s.append(rng.uniform(-1, 1, 1))
        controls.append(u)
    return _rollouts(chain, q0s, qd0s, controls, 0.01, lg.RK4()), np.array(controls)


def test_a_fit_that_meets_invalid_parameters_keeps_the_best_it_found():
    """The data's damping (0.02) lies below what the guessed chains allow (0.1): trial points of the line search
    there make the simulation NaN, which once aborted the fit; the fit now ends at the boundary with finite losses.
    Where the chain checks its parameter at run time instead, the fit stops there and returns the best theta found,
    saying where and why."""
    states, controls = _pendulum_windows(0.02)

    def nan_below(theta):
        return Chain([Link("revolute", 1.0, 1.0, damping=jnp.where(theta[0] < 0.1, jnp.nan, theta[0]), gear=1.0)])

    fit = identify(nan_below, np.array([1.0]), states, controls, 0.01, iterations=10)
    assert fit.failure is None and bool(jnp.all(jnp.isfinite(fit.losses))) and fit.best_iteration == 10
    assert 0.1 <= float(fit.theta[0]) < 0.1 + 1e-6 and float(fit.losses[-1]) < float(fit.losses[0])

    def checked(theta):
        return Chain([Link("revolute", 1.0, 1.0, damping=eqx.error_if(theta[0], theta[0] < 0.1, "damping < 0.1"),
                           gear=1.0)])

    with pytest.warns(RuntimeWarning, match=r"identify: iteration 0: its line search from theta = \[1\.0\] met a "
                                            r"run-time check \(damping < 0\.1\); returning the best theta found, at "
                                            r"iteration 0"):
        stopped = identify(checked, np.array([1.0]), states, controls, 0.01, iterations=10)
    assert float(stopped.theta[0]) == 1.0 and stopped.best_iteration == 0 and "damping < 0.1" in stopped.failure
    np.testing.assert_allclose(stopped.losses, fit.losses[:1], rtol=1e-12)
    with pytest.raises(ValueError, match=r"the loss or its gradient is not finite at theta0 = \[1\.0\]"):
        identify(lambda th: Chain([Link("revolute", 1.0, 1.0, damping=0.05 + jnp.sqrt(th[0] - 1.0), gear=1.0)]),
                 np.array([1.0]), states, controls, 0.01, iterations=2)  # no derivative at theta0
