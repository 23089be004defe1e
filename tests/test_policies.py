"""GRU / MLP policies (layout, shapes, hidden-state resets) and the observation normaliser
(against numpy's mean/variance of the concatenated data)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from policies import GRUPolicy, MLPPolicy, Normalizer


def _count(tree):
    return sum(x.size for x in jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array)))


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
    assert _count(pol) == expected == 705
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


def test_mlp_shapes():
    pol = MLPPolicy(8, 1, 32, key=jax.random.PRNGKey(0))
    a, h = pol(jnp.ones(8), pol.initial_state(), True)
    assert a.shape == (1,) and h.shape == (0,) and float(jnp.abs(a).max()) <= 1
    assert _count(pol) == 8 * 32 + 32 + 32 * 32 + 32 + 32 + 1
    with pytest.raises(ValueError, match="width"):
        MLPPolicy(8, 1, 0, key=jax.random.PRNGKey(0))


def test_normalizer_matches_numpy_and_clips():
    rng = np.random.default_rng(0)
    batches = [rng.normal([1.0, -2.0, 0.0], [0.5, 3.0, 1e-3], size=(n, 3)) for n in (7, 50, 13)]
    norm = Normalizer.create(3)
    for b in batches:
        norm = norm.update(jnp.asarray(b))
    data = np.concatenate(batches)
    np.testing.assert_allclose(norm.mean, data.mean(0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(norm.var, data.var(0), rtol=1e-10)
    assert float(norm.count) == len(data)
    z = norm(jnp.asarray(data))
    expected = np.clip((data - data.mean(0)) / np.sqrt(data.var(0) + 1e-6), -5, 5)
    np.testing.assert_allclose(z, expected, rtol=1e-9, atol=1e-12)
    far = norm(jnp.array([1e3, -1e3, 0.0]))
    np.testing.assert_array_equal(far[:2], [5.0, -5.0])
    # pure: the old object is unchanged by an update
    n0 = Normalizer.create(3)
    n0.update(jnp.ones((4, 3)))
    assert float(n0.count) == 0
    # identity (up to clipping) before any data
    np.testing.assert_allclose(n0(jnp.array([0.5, -1.0, 2.0])), [0.5, -1.0, 2.0], rtol=1e-6)


def test_normalizer_validates():
    with pytest.raises(ValueError, match="clip"):
        Normalizer.create(3, clip=0.0)
