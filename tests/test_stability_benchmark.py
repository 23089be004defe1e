"""``benchmarks/stability.py``'s error-controlled stress rollout: it is ``simulate``'s adaptive mode, and it counts an
interval that reaches ``max_steps`` instead of raising; its contact section's conservative hopper conserves energy to
first order through a landing."""

import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from benchmarks.stability import _adaptive_rollout, _drop, dropped, step_estimate

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


def test_dropped_hopper_conserves_energy_to_first_order():
    """Without contact, limit or joint damping the total energy, penalty springs included, is conserved to first order
    by semi-implicit Euler through the landing: its largest error halves with the step. Both steps run in one compiled
    ``_drop`` (the step a traced argument, the step count that of the finer one); the coarser step's error is read over
    its own 0.4 s, the states of a run of ``round(0.4 / h)`` steps."""
    chain, q0 = dropped("hopper", 2e4, damped=False)
    steps = {h: round(0.4 / h) for h in (1e-3, 5e-4)}
    errors = []
    for h, n in steps.items():
        e, rootz = (np.asarray(x)[: n + 1] for x in _drop(chain, q0[:1], jnp.asarray(h), max(steps.values())))
        assert rootz.min() < 1.25 - 0.04  # the foot (0.04 m above the ground at qpos0) pressed its springs
        errors.append(np.max(np.abs(e - e[0])))
    assert 1.7 < errors[0] / errors[1] < 2.3
    h, m_eff = step_estimate(chain, q0[0])
    assert 0 < m_eff < float(jnp.sum(chain.mass)) and h == pytest.approx(2 * np.sqrt(m_eff / 2e4))
