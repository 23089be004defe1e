"""SHAC's actor and critic (policies/actor_critic.py) against a NumPy re-implementation of their layers
(Linear -> ELU -> LayerNorm, then a linear output), the critic's orthogonal initialisation (``W W^T = 2 I`` and zero
biases), the actor's reparameterised tanh-Gaussian sample by hand, and its rollout interface (the deterministic
action)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from policies.actor_critic import Actor, Critic


def _numpy_mlp(mlp, x):
    """The network by hand: ELU (x or e^x - 1), LayerNorm (eps 1e-5, learned scale and shift), linear output."""
    x = np.asarray(x)
    for lin, norm in zip(mlp.hidden, mlp.norms):
        x = np.asarray(lin.weight) @ x + np.asarray(lin.bias)
        x = np.where(x > 0, x, np.expm1(x))
        x = (x - x.mean()) / np.sqrt(x.var() + 1e-5) * np.asarray(norm.weight) + np.asarray(norm.bias)
    return np.asarray(mlp.out.weight) @ x + np.asarray(mlp.out.bias)


def test_critic_is_orthogonal_with_gain_sqrt2_and_matches_numpy():
    critic = Critic(5, (16, 8), key=jax.random.PRNGKey(0))
    layers = list(critic.net.hidden) + [critic.net.out]
    assert [lin.weight.shape for lin in layers] == [(16, 5), (8, 16), (1, 8)]
    for lin in layers:
        w = np.asarray(lin.weight)
        small = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w  # orthonormal rows or columns, times the gain^2
        np.testing.assert_allclose(small, 2.0 * np.eye(min(w.shape)), rtol=0, atol=1e-12)
        assert not np.asarray(lin.bias).any()
    obs = np.random.default_rng(0).normal(size=(7, 5))
    values = jax.vmap(critic)(jnp.asarray(obs))
    assert values.shape == (7,)
    np.testing.assert_allclose(values, [_numpy_mlp(critic.net, o)[0] for o in obs], rtol=1e-12, atol=1e-12)


def test_actor_sample_and_deterministic_action_by_hand():
    actor = Actor(4, 2, (8, 8), init_log_std=-0.5, key=jax.random.PRNGKey(1))
    np.testing.assert_array_equal(actor.log_std, [-0.5, -0.5])
    obs, key = jnp.array([0.3, -1.2, 0.8, 0.1]), jax.random.PRNGKey(2)
    mu = _numpy_mlp(actor.mu, obs)
    np.testing.assert_allclose(actor.deterministic(obs), np.tanh(mu), rtol=1e-12, atol=1e-14)
    eps = np.asarray(jax.random.normal(key, (2,), jnp.float64))
    np.testing.assert_allclose(actor.sample(obs, key), np.tanh(mu + np.exp(-0.5) * eps), rtol=1e-12, atol=1e-14)
    # reparameterised: the sample is differentiable in log_std, with d a / d log_std = (1 - a^2) sigma eps
    a = np.tanh(mu + np.exp(-0.5) * eps)
    g = jax.jacfwd(lambda s: eqx.tree_at(lambda m: m.log_std, actor, s).sample(obs, key))(actor.log_std)
    np.testing.assert_allclose(np.diag(g), (1 - a**2) * np.exp(-0.5) * eps, rtol=1e-10, atol=1e-14)


def test_the_actor_as_a_rollout_policy_acts_deterministically():
    actor = Actor(3, 1, (8,), key=jax.random.PRNGKey(3))
    h = actor.initial_state()
    assert h.shape == (0,) and h.dtype == actor.log_std.dtype and actor.hidden_size == 0
    obs = jnp.array([0.5, -0.5, 2.0])
    a, h2 = actor(obs, h, True)
    np.testing.assert_array_equal(a, actor.deterministic(obs))
    assert h2.shape == (0,)
