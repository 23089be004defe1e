"""The cross-entropy method (optim/cem.py, ``CEMConfig``: CE-APG's loop without APG steps): a candidate's fitness is
minus the objective of its one batch of episodes (the mean return by default), computed here by hand for zero-policy
candidates; the Gaussian is refitted to the elites; it refuses APG steps."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import optim
from policies import Normalizer
from tests.helpers import pendulum_swingup, states_equal, tiny_gru


def test_fitness_is_the_mean_return_of_the_candidates_episodes():
    task = pendulum_swingup(horizon=20, noise=0.5)
    policy = tiny_gru(task)
    cfg = optim.CEMConfig(num_candidates=3, num_elites=2, iterations=1, episodes=2, init_std=0.0)
    key = jax.random.PRNGKey(4)
    trainer = cfg.make_trainer(task, policy)
    state, metrics = trainer.update(trainer.init(key))
    flat, unravel = optim.flatten_policy(policy)
    zero, norm = unravel(jnp.zeros_like(flat)), Normalizer.create(task.observation_size)
    _, k_run = jax.random.split(jax.random.fold_in(key, 0))
    batch = jax.jit(lambda k: jax.vmap(lambda kk: optim.episode(task, zero, norm, kk))(jax.random.split(k, 2)))
    episodes = [batch(k) for k in jax.random.split(k_run, 3)]
    fit = np.array([float(jnp.mean(e.ret)) for e in episodes])
    assert len(set(fit.tolist())) == 3
    np.testing.assert_allclose(metrics["best_return"], fit.max(), rtol=1e-12)
    np.testing.assert_allclose(metrics["elite_return"], np.sort(fit)[-2:].mean(), rtol=1e-12)
    np.testing.assert_allclose(metrics["mean_return"], fit.mean(), rtol=1e-12)
    assert metrics["env_steps"] == 3 * 2 * 20
    # std 0: the candidates are the mean (zeros), so are the elites and the refit; the normaliser is the mean of the
    # two elites' normalisers, each of which absorbed its own batch's observations
    assert not bool(jnp.any(state.mean)) and not bool(jnp.any(state.std))
    elites = np.argsort(-fit)[:2]
    means = [norm.update(episodes[i].obs).mean for i in elites]
    np.testing.assert_allclose(state.normalizer.mean, np.mean(means, axis=0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(state.best_normalizer.mean, means[0], rtol=1e-12, atol=1e-14)


def test_cem_refuses_apg_steps():
    with pytest.raises(ValueError, match=r"CEMConfig\.apg_steps must be 0 \(CEM has no gradient steps\), got 3"):
        optim.CEMConfig(apg_steps=3)


def test_cem_never_updates_the_authors_normalizer():
    task = pendulum_swingup(horizon=20, noise=0.5)
    cfg = optim.CEMConfig(num_candidates=2, num_elites=1, iterations=1, episodes=1, authors_normalizer=True)
    trainer = cfg.make_trainer(task, tiny_gru(task))
    init = trainer.init(jax.random.PRNGKey(0))
    state, _ = trainer.update(init)
    assert states_equal((state.normalizer, state.best_normalizer), (init.normalizer, init.normalizer))
    assert float(state.normalizer.steps) == 0.0
