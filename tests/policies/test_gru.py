"""The CE-APG authors' recurrent policy (policies/gru.py): its layout (parameter count by hand), shapes, bounded
and deterministic actions, hidden-state resets and memory."""

import jax
import jax.numpy as jnp
import numpy as np

from policies import GRUPolicy
from tests.helpers import param_count


def test_gru_layout_and_shapes():
    obs, H = 4, 16
    pol = GRUPolicy(obs, 1, H, key=jax.random.PRNGKey(0))
    h = pol.initial_state()
    assert h.shape == (obs,) and not h.any()
    a, h2 = pol(jnp.ones(obs), h)
    assert a.shape == (1,) and h2.shape == (obs,)
    # Dense(H) -> GRU(hidden = obs) -> Dense(H) -> Dense(H) -> Dense(1): the authors' layout
    gru = 3 * obs * H + 3 * obs * obs + 3 * obs + obs  # eqx GRUCell: W_ih, W_hh, bias, bias_n
    expected = (obs * H + H) + gru + (obs * H + H) + (H * H + H) + (H + 1)
    assert param_count(pol) == expected == 705
    big = GRUPolicy(8, 1, 32, key=jax.random.PRNGKey(0))
    assert big.fc2.weight.shape == (32, 32) and big.hidden_size == 8


def test_gru_actions_bounded_and_deterministic():
    pol = GRUPolicy(4, 2, 16, key=jax.random.PRNGKey(1))
    pol = jax.tree_util.tree_map(lambda x: 30 * x if eqx_array(x) else x, pol)
    x = 10 * jax.random.normal(jax.random.PRNGKey(2), (64, 4))
    a, _ = jax.vmap(pol, in_axes=(0, None))(x, pol.initial_state())
    assert float(jnp.max(jnp.abs(a))) <= 1.0
    a2, _ = jax.vmap(pol, in_axes=(0, None))(x, pol.initial_state())
    np.testing.assert_array_equal(a, a2)


def eqx_array(x):
    return isinstance(x, jax.Array)


def test_gru_hidden_state_reset():
    pol = GRUPolicy(4, 1, 16, key=jax.random.PRNGKey(3))
    obs = jnp.array([0.3, -0.2, 1.0, 0.5])
    h = jnp.array([0.9, -0.7, 0.4, 0.2])
    a_reset, h_reset = pol(obs, h, True)
    a_fresh, h_fresh = pol(obs, pol.initial_state(), False)
    np.testing.assert_array_equal(a_reset, a_fresh)
    np.testing.assert_array_equal(h_reset, h_fresh)
    a_carry, h_carry = pol(obs, h, False)
    assert not np.allclose(h_carry, h_fresh)  # the memory matters when it is not reset
    # under jit, with a traced flag (jnp.where, not Python control flow)
    # (jit may fuse differently from eager mode: equal to float64 round-off)
    f = jax.jit(lambda r: pol(obs, h, r))
    np.testing.assert_allclose(f(jnp.array(True))[1], h_fresh, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(f(jnp.array(False))[1], h_carry, rtol=1e-14, atol=1e-15)


def test_gru_memory_carries_information():
    """The same observation sequence gives different actions after different histories."""
    pol = GRUPolicy(2, 1, 16, key=jax.random.PRNGKey(4))
    h1 = pol(jnp.array([3.0, 0.0]), pol.initial_state())[1]
    h2 = pol(jnp.array([-3.0, 0.0]), pol.initial_state())[1]
    a1 = pol(jnp.zeros(2), h1)[0]
    a2 = pol(jnp.zeros(2), h2)[0]
    assert not np.allclose(a1, a2)
