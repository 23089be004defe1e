"""``benchmarks/stability.py``'s error-controlled stress rollout: it is ``simulate``'s adaptive mode, and it counts an
interval that reaches ``max_steps`` instead of raising."""

import jax.numpy as jnp
import numpy as np

import lagrange as lg
from benchmarks.stability import _adaptive_rollout

CHAIN = lg.systems.n_link_pendulum(2)
Q0, QD0 = jnp.array([2.0, -1.0]), jnp.array([300.0, -400.0])  # several steps, some rejected, per 1 ms


def test_adaptive_rollout_is_simulates_adaptive_mode():
    ref = lg.simulate(CHAIN, Q0, QD0, None, 1e-3, lg.Tsit5(), steps=20, rtol=1e-8, atol=1e-8)
    q, qd, accepted, rejected, busiest, hit, failed = _adaptive_rollout(CHAIN, Q0, QD0, 1e-3, 20, 1e-8, 1e-8, 4096)
    np.testing.assert_allclose(q, ref.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qd, ref.qd, rtol=0, atol=1e-10)
    assert not hit and not failed
    assert accepted > 20 and rejected > 0 and busiest <= accepted + rejected


def test_adaptive_rollout_counts_max_steps_instead_of_raising():
    q, qd, accepted, rejected, busiest, hit, failed = _adaptive_rollout(CHAIN, Q0, QD0, 1e-3, 20, 1e-8, 1e-8, 2)
    assert hit and failed and busiest == 2
    assert jnp.all(q[-1] == q[-2]) and jnp.all(qd[-1] == qd[-2])  # the state is held after the stop
