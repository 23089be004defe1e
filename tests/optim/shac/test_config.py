"""SHAC's config (optim/shac/config.py): the linear learning-rate decay by hand, errors naming the field, and the
``bodies`` field reaching the trainer's task."""

from __future__ import annotations

import numpy as np
import pytest

from lagrange.tasks import make_task
from optim import shac


def test_learning_rates_decay_linearly_to_lr_end():
    cfg = shac.SHACConfig(epochs=500)
    a0, c0 = cfg.learning_rates(0)
    a1, c1 = cfg.learning_rates(250)
    a2, c2 = cfg.learning_rates(500)
    np.testing.assert_allclose([a0, c0], [1e-2, 1e-3], rtol=1e-6)
    np.testing.assert_allclose([a1, c1], [(1e-2 + 1e-5) / 2, (1e-3 + 1e-5) / 2], rtol=1e-6)
    np.testing.assert_allclose([a2, c2], [1e-5, 1e-5], rtol=1e-6)


def test_config_errors_name_the_field():
    for kwargs, field in (({"gamma": 1.5}, "gamma"), ({"num_envs": 0}, "num_envs"), ({"task": "nope"}, "task"),
                          ({"actor_units": (64, 0)}, "actor_units"), ({"adam_b1": 1.0}, "adam_b1"),
                          ({"lam": -0.1}, "lam"), ({"critic_minibatches": 10**6}, "critic_minibatches"),
                          ({"task": "acrobot", "bodies": "capsules"}, r"bodies must be one of \['rods', 'brax_v1'\]"),
                          ({"bodies": "brax_v1"}, "SHACConfig.bodies='brax_v1' is for the paper tasks")):
        with pytest.raises(ValueError, match=field):
            shac.SHACConfig(**kwargs)


def test_bodies_field_builds_the_brax_v1_task():
    """``SHACConfig.bodies`` reaches the trainer's task, as ``CEAPGConfig.bodies`` does (benchmarks/algorithms.py
    --bodies trains SHAC on the authors' Brax v1 acrobot through it)."""
    cfg = dict(num_envs=4, short_horizon=4, epochs=2, critic_iterations=1, critic_minibatches=1)
    rods = shac.make_trainer(shac.SHACConfig(task="acrobot", **cfg)).task
    brax = shac.make_trainer(shac.SHACConfig(task="acrobot", bodies="brax_v1", **cfg)).task
    for task, bodies in ((rods, "rods"), (brax, "brax_v1")):
        want = make_task("acrobot", bodies).chain
        for field in ("mass", "length", "com", "inertia"):
            np.testing.assert_array_equal(getattr(task.chain, field), getattr(want, field))
    assert not np.allclose(brax.chain.inertia, rods.chain.inertia)
