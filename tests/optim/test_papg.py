"""Parallel APG (optim/papg.py): independent runs from their own initialisations, and the policy it shows is the run
with the best fitness."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import optim
from tests.helpers import RUN_KEY


def test_papg_keeps_the_best_run(short_run):
    result, _, _, policy, steps = short_run("PAPGConfig")  # 2 runs, 2 iterations
    trainer, state = result.trainer, result.state
    init = trainer.init(RUN_KEY)
    for i, k in enumerate(jax.random.split(jax.random.fold_in(RUN_KEY, 0x5EED), 2)):  # each from its own reinit
        np.testing.assert_array_equal(init.params[i], optim.flatten_policy(policy.reinit(k))[0])
    assert bool(jnp.all(init.fitness == -jnp.inf))
    i = int(jnp.argmax(state.fitness))
    assert result.history[-1]["best_return"] == float(state.fitness[i])
    assert result.history[-1]["env_steps"] == 2 * steps == 2 * (2 * 2 * 1 * 20)
    shown, norm = trainer.policy(state)
    np.testing.assert_array_equal(optim.flatten_policy(shown)[0], state.params[i])
    np.testing.assert_array_equal(norm.mean, state.normalizers.mean[i])
    assert len(set(np.asarray(state.fitness).tolist())) == 2  # independent runs
    assert not np.array_equal(state.params[0], state.params[1])
    with pytest.raises(ValueError, match="PAPG has only its best run"):
        trainer.policy(state, "mean")
