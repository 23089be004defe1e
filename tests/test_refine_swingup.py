"""benchmarks/refine_swingup.py: per-start refinement of a policy's episodes by a time-varying action offset."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks import refine_swingup as rs
from lagrange import tasks
from optim import ce_apg
from optim._loop import run
from optim.apg import episode


def test_arrival_is_the_first_step_of_the_final_hold():
    task = tasks.acrobot()
    up = np.array([np.pi, 0.0])
    q = np.tile(up, (3, 30, 1))
    q[0, :7, 0] = 0.0  # hanging for 7 steps, then up to the end
    q[0, 3, 0] = np.pi  # a pass through upright before that does not count
    q[1, -1, 1] = 0.5  # bent at the very last step: never settled
    assert rs.arrival(task, q) == [7, None, 0]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("runs")
    cfg = ce_apg.CEAPGConfig.laptop("acrobot", num_candidates=2, num_elites=1, iterations=1, apg_steps=2,
                                    fitness_window=1, episodes=1, horizon=40)
    trainer = ce_apg.make_trainer(cfg)
    state, _ = run(trainer, jax.random.PRNGKey(3), iterations=1, progress=False,
                   ckpt_path=str(folder / "ce_apg_acrobot_3.eqx"))
    return folder, trainer, state


def test_zero_offset_is_the_policys_episode(tiny_run):
    _, trainer, state = tiny_run
    policy, norm = trainer.policy(state)
    task = trainer.task
    key = jax.random.PRNGKey(11)
    own = episode(task, policy, norm, key)
    ret, rewards, q = rs.rollout(task, policy, norm, task.reset(key), jnp.zeros((task.horizon, task.action_size)))
    # only tanh(atanh(a)) round-off separates them (float64 here, 40 steps: no room for chaos to grow it)
    np.testing.assert_allclose(np.asarray(q), np.asarray(own.q), atol=1e-12)
    np.testing.assert_allclose(float(ret), float(own.ret), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(rewards), np.asarray(own.rewards), atol=1e-12)


def test_refinement_raises_every_start_and_reports_it(tiny_run, tmp_path):
    folder, trainer, _ = tiny_run
    out = tmp_path / "refine.json"
    rs.main(["--runs", str(folder), "--seeds", "3", "--steps", "30", "--lr", "0.1", "--out", str(out)])
    row = json.loads(out.read_text())["rows"][0]
    assert len(row["policy_returns"]) == rs.EVAL_EPISODES
    np.testing.assert_allclose(row["zero_offset_returns"], row["policy_returns"], rtol=1e-12)
    refined, start = np.array(row["refined_returns"]), np.array(row["zero_offset_returns"])
    # 30 Adam steps on a 40-step episode from hanging: every start gains (the optimiser really moves the offset)
    assert np.all(refined > start + 1.0), refined - start
    assert row["max_abs_offset"] > 0.1
    # an untrained 40-step policy never gets the arm up: no arrival, no balance
    assert row["arrival_step"] == [None] * rs.EVAL_EPISODES and not any(row["refined_balanced"])


def test_a_missing_checkpoint_names_the_command_that_makes_it(tmp_path):
    with pytest.raises(SystemExit, match="paper_tables.py"):
        rs.main(["--runs", str(tmp_path), "--seeds", "0"])
