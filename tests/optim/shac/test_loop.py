"""SHAC's host loop (optim/shac/loop.py, ``shac.run``): it takes the trainer's own updates (its state equals a
manual init-and-update loop bit for bit), counts env steps and epochs, evaluates at epoch 0, every ``eval_every``
epochs and after the last on the same starts (the last evaluation is ``trainer.evaluate`` of the final state), and
refuses bad counts naming them."""

import jax
import numpy as np
import pytest

from optim import shac
from tests.helpers import pendulum_swingup


@pytest.fixture(scope="module")
def tiny():
    cfg = shac.SHACConfig(task="custom", num_envs=4, short_horizon=4, epochs=3, critic_iterations=2,
                          critic_minibatches=2, actor_units=(8,), critic_units=(8,))
    return shac.make_trainer(cfg, pendulum_swingup())


def test_run_is_the_trainers_updates_with_its_evaluations(tiny):
    key, eval_key = jax.random.PRNGKey(0), jax.random.PRNGKey(5)
    state, history, curve = shac.run(tiny, key, eval_every=2, eval_episodes=4, eval_key=eval_key, progress=False)
    manual = tiny.init(key)
    for _ in range(3):
        manual, _ = tiny.update(manual)
    for a, b in zip(jax.tree_util.tree_leaves(state), jax.tree_util.tree_leaves(manual)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert [h["epoch"] for h in history] == [1, 2, 3]
    assert [h["env_steps"] for h in history] == [16.0, 32.0, 48.0]  # 4 envs x 4-step windows per epoch
    assert [c["epoch"] for c in curve] == [0, 2, 3] and [c["env_steps"] for c in curve] == [0.0, 32.0, 48.0]
    rets, bal = tiny.evaluate(state, eval_key, 4)
    np.testing.assert_allclose(curve[-1]["return"], float(np.mean(rets)), rtol=1e-12)
    np.testing.assert_allclose(curve[-1]["return_std"], float(np.std(rets)), rtol=1e-12, atol=1e-12)
    assert curve[-1]["balanced"] == float(np.mean(bal))
    first, _ = tiny.evaluate(tiny.init(key), eval_key, 4)
    np.testing.assert_allclose(curve[0]["return"], float(np.mean(first)), rtol=1e-12)


@pytest.mark.parametrize("kwargs, name", [({"epochs": 0}, "epochs"), ({"epochs": True}, "epochs"),
                                          ({"eval_every": 0}, "eval_every"), ({"eval_every": 1.5}, "eval_every")])
def test_run_rejects_bad_counts(tiny, kwargs, name):
    with pytest.raises(ValueError, match=rf"{name} must be an integer >= 1"):
        shac.run(tiny, jax.random.PRNGKey(0), progress=False, **kwargs)
