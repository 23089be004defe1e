"""SHAC's trainer (optim/shac/trainer.py): the target critic against the soft-update formula, a state that
round-trips through a checkpoint and continues exactly, and the whole algorithm by the return it reaches on a small
problem (a pendulum swing-up, above 600 of 1000). Its losses are checked in test_losses.py, the authors' cartpole in
tests/lagrange/test_shac_cartpole.py."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from optim import shac
from tests.helpers import pendulum_swingup


@pytest.fixture(scope="module")
def tiny():
    """A tiny SHAC trainer on the pendulum (one compilation shared by the tests that use it)."""
    cfg = shac.SHACConfig(task="custom", num_envs=4, short_horizon=4, epochs=10, critic_iterations=2,
                          critic_minibatches=2, actor_units=(8,), critic_units=(8,), target_alpha=0.3)
    return cfg, shac.make_trainer(cfg, pendulum_swingup())


def test_soft_update_formula_and_trainer_uses_it(tiny):
    a = {"w": jnp.array([1.0, 2.0]), "b": jnp.array(3.0)}
    b = {"w": jnp.array([5.0, -2.0]), "b": jnp.array(-1.0)}
    out = shac.soft_update(a, b, 0.2)
    np.testing.assert_allclose(out["w"], [0.2 * 1 + 0.8 * 5, 0.2 * 2 - 0.8 * 2], rtol=1e-15)
    np.testing.assert_allclose(out["b"], 0.2 * 3 - 0.8 * 1, rtol=1e-15)
    # In one epoch of the trainer: new target = alpha * old target + (1 - alpha) * new critic.
    cfg, tr = tiny
    assert cfg.target_alpha == 0.3
    s0 = tr.init(jax.random.PRNGKey(0))
    s0 = s0._replace(target_critic=jax.tree_util.tree_map(lambda x: x + 0.5, s0.target_critic))
    s1, _ = tr.update(s0)
    assert not np.allclose(np.asarray(s1.critic.net.out.weight), np.asarray(s0.critic.net.out.weight))
    for t1, t0, c1 in zip(jax.tree_util.tree_leaves(s1.target_critic), jax.tree_util.tree_leaves(s0.target_critic),
                          jax.tree_util.tree_leaves(s1.critic)):
        np.testing.assert_allclose(t1, 0.3 * t0 + 0.7 * c1, rtol=1e-13, atol=1e-15)


def test_state_round_trips_through_a_checkpoint(tiny, tmp_path):
    """A SHAC state saved with optim.checkpoint and loaded back continues exactly like the original."""
    from optim import checkpoint

    cfg, tr = tiny
    config = json.loads(json.dumps(dataclasses.asdict(cfg)))
    s1, _ = tr.update(tr.init(jax.random.PRNGKey(0)))
    path = tmp_path / "shac.eqx"
    checkpoint.save(path, s1, config=config, iteration=1)
    loaded, head = checkpoint.load(path, tr.init(jax.random.PRNGKey(1)), config=config)
    assert head["iteration"] == 1 and int(loaded.iteration) == 1
    a, _ = tr.update(s1)
    b, _ = tr.update(loaded)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_shac_improves_a_pendulum_swingup():
    """make_train (the whole run under one jit): 100 epochs x 32 envs x 16-step windows (5e4 simulated
    steps) lift the deterministic return over 16 random starts of the pendulum swing-up (max 1000) from
    the untrained policy's (about 50 at this seed) above 600. (The authors' cartpole with their full
    config: examples/shac_cartpole.py.)"""
    cfg = shac.SHACConfig(task="custom", num_envs=32, epochs=100, short_horizon=16)
    task = pendulum_swingup()
    trainer = shac.make_trainer(cfg, task)
    key, eval_key = jax.random.PRNGKey(0), jax.random.PRNGKey(1)
    before, _ = trainer.evaluate(trainer.init(key), eval_key, 16)
    state, metrics = jax.jit(shac.make_train(cfg, task))(key)
    after, _ = trainer.evaluate(state, eval_key, 16)
    assert int(state.iteration) == 100
    assert float(jnp.sum(metrics["env_steps"])) == 100 * 32 * 16
    assert int(jnp.sum(metrics["nonfinite"])) == 0
    assert float(jnp.mean(before)) < 200
    assert float(jnp.mean(after)) > 600, float(jnp.mean(after))
