"""What every algorithm is (optim/base.py): a config that round-trips through the JSON a checkpoint header stores (and
refuses an unknown algorithm or field by name), and a trainer whose ``scan_train`` (the whole run as one jittable
function) reaches the state of the host loop of ``update`` calls."""

import dataclasses

import jax
import numpy as np
import pytest

import optim
from optim.base import config_from_dict, config_to_dict
from tests.helpers import RUN_KEY

CONFIGS = [optim.CEAPGConfig.laptop("acrobot", warmup_horizons=[300, 400], warmup_iterations=20),
           optim.CEMConfig(num_candidates=50), optim.PAPGConfig(num_runs=3, truncation=7),
           optim.APGConfig(learning_rate=3e-4), optim.SHACConfig(critic_units=(32, 16), actor_grad_norm=None)]


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: type(c).__name__)
def test_config_round_trips_through_its_json(cfg):
    saved = config_to_dict(cfg)
    assert saved["algorithm"] == type(cfg).__name__
    assert {k for k in saved if k != "algorithm"} == {f.name for f in dataclasses.fields(cfg)}
    back = config_from_dict(saved)
    assert type(back) is type(cfg) and back == cfg  # tuples (stored as JSON lists) come back as tuples
    assert isinstance(cfg, optim.AlgorithmConfig)


def test_config_from_dict_names_what_it_does_not_know():
    saved = config_to_dict(optim.APGConfig())
    with pytest.raises(ValueError, match=r"unknown algorithm 'PPOConfig'; known: \[.*'APGConfig'.*'SHACConfig'"):
        config_from_dict(dict(saved, algorithm="PPOConfig"))
    with pytest.raises(ValueError, match=r"config fields \['later_field'\] are not fields of APGConfig"):
        config_from_dict(dict(saved, later_field=1))
    with pytest.raises(ValueError, match=r"APGConfig\.episodes"):  # the config's own checks run
        config_from_dict(dict(saved, episodes=0))
    with pytest.raises(TypeError, match=r"a saved config must be a dict \(config_to_dict's\), got list"):
        config_from_dict([saved])


def test_algorithm_config_is_abstract():
    with pytest.raises(TypeError, match="abstract"):
        optim.AlgorithmConfig()


def test_scan_train_is_the_host_loop(short_run):
    """``scan_train(trainer)(key)`` (lax.scan over the config's iterations) reaches the state of the host loop
    (``optim.train``'s run); the stacked metrics have one entry per iteration. (APG here; CE-APG's sharded update with
    its warm-up stages inside the scan in test_ce_apg.py.)"""
    result = short_run("APGConfig")[0]
    state, metrics = jax.jit(optim.scan_train(result.trainer))(RUN_KEY)
    assert int(state.iteration) == 2 and metrics["best_return"].shape == (2,)
    # the same iteration inside a scan: XLA may fuse it differently, float64 round-off
    for a, b in zip(jax.tree_util.tree_leaves(state), jax.tree_util.tree_leaves(result.state)):
        np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(metrics["best_return"], [h["best_return"] for h in result.history], rtol=1e-9)
