"""SHAC's config (optim/shac/config.py): the authors' cartpole settings as the defaults, the linear learning-rate
decay by hand, and the task and actor it is given (its body set; the actor's architecture, with weights drawn from the
run's key); it trains a stochastic ``policies.Actor`` only. Every field's validation: tests/optim/test_validate.py."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import optim
from lagrange.tasks import Acrobot
from policies import Actor, GRUPolicy
from tests.helpers import pendulum_swingup


def test_defaults_are_the_authors_cartpole_settings():
    cfg = optim.SHACConfig()
    assert (cfg.num_envs, cfg.short_horizon, cfg.iterations, cfg.gamma, cfg.lam) == (64, 32, 500, 0.99, 0.95)
    assert (cfg.critic_iterations, cfg.critic_minibatches, cfg.target_alpha) == (16, 4, 0.2)
    assert (cfg.actor_lr, cfg.critic_lr, cfg.lr_end, cfg.adam_b1, cfg.adam_b2, cfg.adam_eps) == \
        (1e-2, 1e-3, 1e-5, 0.7, 0.95, 1e-8)
    assert (cfg.actor_grad_norm, cfg.critic_grad_norm, cfg.critic_units, cfg.normalize) == (1.0, 1.0, (64, 64), True)
    assert cfg.env_steps_per_epoch() == 64 * 32



def test_bptt_presets_are_the_authors_bptt_settings():
    """``examples/cfg/bptt/{hopper,cheetah,ant,humanoid}.yaml`` in NVlabs/DiffRL: 32 actors, 128 steps (1000 for the
    3-D tasks), 2000 epochs, lr 1e-3 / 2e-3 / 4e-3 / 2e-3 decayed linearly to 1e-5, betas (0.7, 0.95), grad norm 1,
    obs_rms; no critic; the SNU humanoid's 16 actors x 1000 steps."""
    for task, window, lr, envs in (("hopper", 128, 1e-3, 32), ("cheetah", 128, 2e-3, 32), ("ant", 1000, 4e-3, 32),
                                   ("humanoid", 1000, 2e-3, 32), ("snu_humanoid", 1000, 2e-3, 16)):
        cfg = optim.SHACConfig.bptt(task)
        assert (cfg.num_envs, cfg.short_horizon, cfg.iterations, cfg.actor_lr, cfg.lr_end) == (envs, window, 2000, lr,
                                                                                               1e-5)
        assert (cfg.adam_b1, cfg.adam_b2, cfg.actor_grad_norm, cfg.normalize, cfg.gamma) == (0.7, 0.95, 1.0, True, 0.99)
        assert not cfg.use_critic and cfg.env_steps_per_epoch() * cfg.iterations == envs * window * 2000
    assert optim.SHACConfig.bptt("hopper", iterations=3).iterations == 3
    with pytest.raises(ValueError, match=r"task must be one of \['ant', 'cheetah', 'hopper', 'humanoid', "
                                         r"'snu_humanoid'\], got 'x'"):
        optim.SHACConfig.bptt("x")


def test_the_3d_presets_are_the_authors_settings():
    """``examples/cfg/shac/ant.yaml`` and ``humanoid.yaml``: 64 actors x 32 steps x 2000 epochs; the ant's actor and
    critic lr 2e-3 and target alpha 0.2; the humanoid's critic lr 5e-4, alpha 0.995, critic (128, 128)."""
    ant, hum, snu = optim.SHACConfig.ant(), optim.SHACConfig.humanoid(), optim.SHACConfig.snu_humanoid()
    assert (snu.num_envs, snu.iterations, snu.actor_lr, snu.critic_lr, snu.target_alpha, snu.critic_units) == (
        64, 2000, 2e-3, 5e-4, 0.995, (256, 256))  # examples/cfg/shac/snu_humanoid.yaml
    for cfg in (ant, hum):
        assert (cfg.num_envs, cfg.short_horizon, cfg.iterations, cfg.actor_lr, cfg.lam) == (64, 32, 2000, 2e-3, 0.95)
        assert (cfg.critic_iterations, cfg.critic_minibatches, cfg.adam_b1, cfg.adam_b2) == (16, 4, 0.7, 0.95)
    assert (ant.critic_lr, ant.target_alpha, ant.critic_units) == (2e-3, 0.2, (64, 64))
    assert (hum.critic_lr, hum.target_alpha, hum.critic_units) == (5e-4, 0.995, (128, 128))


def test_without_a_critic_an_epoch_trains_the_actor_and_leaves_the_critic():
    task = pendulum_swingup(horizon=10)
    cfg = optim.SHACConfig(num_envs=4, short_horizon=4, iterations=2, critic_units=(6,), use_critic=False)
    trainer = cfg.make_trainer(task, Actor.for_task(task, units=(8,)))
    s0 = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    s1, m = trainer.update(s0)
    assert np.isnan(float(m["value_loss"])) and float(m["grad_norm"]) > 0
    assert not np.array_equal(s1.actor.mu.out.weight, s0.actor.mu.out.weight)
    for a, b in zip(jax.tree_util.tree_leaves(s1.critic), jax.tree_util.tree_leaves(s0.critic)):
        np.testing.assert_array_equal(a, b)

def test_learning_rates_decay_linearly_to_lr_end():
    cfg = optim.SHACConfig(iterations=500)
    a0, c0 = cfg.learning_rates(0)
    a1, c1 = cfg.learning_rates(250)
    a2, c2 = cfg.learning_rates(500)
    np.testing.assert_allclose([a0, c0], [1e-2, 1e-3], rtol=1e-6)
    np.testing.assert_allclose([a1, c1], [(1e-2 + 1e-5) / 2, (1e-3 + 1e-5) / 2], rtol=1e-6)
    np.testing.assert_allclose([a2, c2], [1e-5, 1e-5], rtol=1e-6)


def test_the_task_and_actor_are_taken_as_given():
    """SHAC trains on the task it is given (the authors' Brax v1 acrobot here), and the actor's architecture
    (hidden units, initial log-std) is kept while its weights are drawn from the run's key."""
    task = Acrobot.brax_v1(horizon=20)
    actor = Actor.for_task(task, units=(8, 4), init_log_std=-0.5)
    cfg = optim.SHACConfig(num_envs=4, short_horizon=4, iterations=2, critic_iterations=1, critic_minibatches=1,
                           critic_units=(6,))
    trainer = cfg.make_trainer(task, actor)
    assert trainer.task is task and task.bodies == "brax_v1"
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    assert tuple(layer.out_features for layer in state.actor.mu.hidden) == (8, 4)
    assert bool(jnp.all(state.actor.log_std == -0.5)) and state.actor.log_std.shape == (task.action_size,)
    assert not np.array_equal(state.actor.mu.out.weight, actor.mu.out.weight)  # fresh weights from the key
    assert state.critic.net.hidden[0].out_features == 6 and state.env_state.q.shape == (4, task.chain.nq)
    with pytest.raises(TypeError, match="SHAC trains a stochastic policies.Actor, got GRUPolicy"):
        cfg.make_trainer(task, GRUPolicy.for_task(task))
