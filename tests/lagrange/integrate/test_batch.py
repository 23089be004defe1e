"""``lagrange.simulate_batch``: the same trajectories and gradients as ``jax.vmap(simulate)``, and every failure
naming the member of the batch it happened to (under ``jax.vmap(simulate)`` a check cannot say which)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg

CHAIN = lg.systems.acrobot()
T, DT = 40, 0.01


def _starts(b=4):
    q0 = jnp.stack([jnp.array([0.1 * i, -0.05 * i]) for i in range(b)])
    return q0, jnp.zeros((b, 2)).at[:, 1].set(0.3)


def test_equals_vmap_of_simulate_with_shared_and_per_member_controls():
    q0, qd0 = _starts()
    shared = jnp.sin(jnp.arange(T))[:, None]
    per = jnp.stack([shared * (i + 1) for i in range(4)])
    for u, axis in ((shared, None), (per, 0)):
        got = lg.simulate_batch(CHAIN, q0, qd0, u, DT, lg.RK4(), 2)
        want = jax.vmap(lambda a, b, c: lg.simulate(CHAIN, a, b, c, DT, lg.RK4(), 2), (0, 0, axis))(q0, qd0, u)
        np.testing.assert_array_equal(got.q, want.q)
        np.testing.assert_array_equal(got.qd, want.qd)
        assert got.q.shape == (4, T + 1, 2)
    # gradients pass the checks unchanged
    loss = lambda f: lambda q: jnp.sum(f(q).q[:, -1] ** 2)  # noqa: E731
    g = jax.grad(loss(lambda q: lg.simulate_batch(CHAIN, q, qd0, shared, DT)))(q0)
    g_ref = jax.grad(loss(lambda q: jax.vmap(lambda a, b: lg.simulate(CHAIN, a, b, shared, DT))(q, qd0)))(q0)
    np.testing.assert_array_equal(g, g_ref)


def test_a_member_that_blows_up_is_named():
    q0, qd0 = _starts()
    qd0 = qd0.at[2, 0].set(1e200)  # finite, but the step overflows
    run = eqx.filter_jit(lambda a, b: lg.simulate_batch(CHAIN, a, b, jnp.zeros((T, 1)), DT))
    with pytest.raises(Exception, match=r"member 2 of 4 became non-finite .*simulate\(chain, q0\[2\], qd0\[2\]"):
        jax.block_until_ready(run(q0, qd0))
    assert bool(jnp.all(jnp.isfinite(lg.simulate_batch(CHAIN, q0, qd0, jnp.zeros((T, 1)), DT, check=False).q[:2])))


def test_a_non_finite_start_or_control_is_named_by_member():
    q0, qd0 = _starts()
    with pytest.raises(ValueError, match=r"qd0 must be finite, got inf in member 3 at index \(1,\)"):
        lg.simulate_batch(CHAIN, q0, qd0.at[3, 1].set(jnp.inf), jnp.zeros((T, 1)), DT)
    u = jnp.zeros((4, T, 1)).at[1, 7, 0].set(jnp.nan)
    with pytest.raises(ValueError, match=r"controls must be finite, got nan in member 1 at index \(7, 0\)"):
        lg.simulate_batch(CHAIN, q0, qd0, u, DT)
    traced = eqx.filter_jit(lambda a: lg.simulate_batch(CHAIN, a, qd0, jnp.zeros((T, 1)), DT))
    with pytest.raises(Exception, match="q0 of member 1 of 4 is not finite"):
        jax.block_until_ready(traced(q0.at[1, 0].set(jnp.nan)))


def test_shapes_are_checked_by_name():
    q0, qd0 = _starts()
    with pytest.raises(ValueError, match=r"q0 and qd0 must have shapes \(B, 2\) and \(B, 2\) for this tree, got "
                                         r"\(2,\)"):
        lg.simulate_batch(CHAIN, q0[0], qd0[0], jnp.zeros((T, 1)), DT)
    with pytest.raises(ValueError, match=r"must have B = 4 \(q0's\), got \(3, 40, 1\)"):
        lg.simulate_batch(CHAIN, q0, qd0, jnp.zeros((3, T, 1)), DT)
