"""Parallel APG (optim/papg.py): its config check names the field, and it keeps the best of its independent runs."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from optim import apg, papg


def test_bad_config_names_the_field():
    with pytest.raises(ValueError, match="num_runs"):
        papg.PAPGConfig(num_runs=0)


def test_papg_keeps_the_best_run():
    cfg = papg.PAPGConfig(task="acrobot", num_runs=3, iterations=1, apg_steps=2, episodes=1, horizon=20, width=4,
                          fitness_window=1)
    trainer = papg.make_trainer(cfg)
    state, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
    i = int(jnp.argmax(state.fitness))
    assert float(metrics["best_return"]) == float(state.fitness[i])
    policy, _ = trainer.policy(state)
    flat, _ = apg.flatten_policy(policy)
    np.testing.assert_array_equal(flat, state.params[i])
    assert len(set(np.asarray(state.fitness).tolist())) == 3  # independent runs
