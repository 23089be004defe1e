"""benchmarks/hold_duration.py: when a trained policy's hold ends, past the episode's horizon."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

from benchmarks import hold_duration as hd
from lagrange import tasks
from optim import ce_apg
from optim._loop import run
from optim.apg import evaluate


def test_leaves_upright_finds_the_first_step_past_the_tolerance():
    task = tasks.acrobot()
    up = np.array([np.pi, 0.0])  # absolute orientation of both links: upright
    q = np.tile(up, (2, 30, 1))
    q[0, 12:, 1] = 0.3  # elbow bent 0.3 rad from step 12: the second link is 0.3 rad off
    q[1, 5:, 0] = np.pi - 0.2  # first link 0.2 rad off: within 0.25
    assert hd.leaves_upright(task, q, tolerance=0.25, from_step=0) == [12, None]
    assert hd.leaves_upright(task, q, tolerance=0.25, from_step=20) == [20, None]
    assert hd.leaves_upright(task, q, tolerance=0.1, from_step=0) == [12, 5]


def test_runs_a_checkpoint_past_its_horizon(tmp_path):
    cfg = ce_apg.CEAPGConfig.laptop("acrobot", num_candidates=2, num_elites=1, iterations=1, apg_steps=2, fitness_window=1,
                                    episodes=1, horizon=20)
    trainer = ce_apg.make_trainer(cfg)
    state, _ = run(trainer, jax.random.PRNGKey(3), iterations=1, progress=False,
                   ckpt_path=str(tmp_path / "ce_apg_acrobot_3.eqx"))
    out = tmp_path / "hold.json"
    hd.main(["--runs", str(tmp_path), "--seeds", "3", "--steps", "50", "--from-step", "0", "--out", str(out)])
    row = json.loads(out.read_text())["rows"][0]
    policy, norm = trainer.policy(state)
    rets, bal = evaluate(trainer.task, policy, norm, jax.random.PRNGKey(10_003), hd.EVAL_EPISODES)
    assert row["return"] == pytest.approx(float(np.mean(rets)), rel=1e-6)  # the paper-tables evaluation's episodes
    assert row["balanced"] == [bool(b) for b in np.asarray(bal)]
    assert row["prefix_max_abs_difference"] == 0.0  # the longer run begins as the task's own episode
    # an untrained policy hangs: every episode is far from upright at step 0
    assert row["leaves_upright_at"] == [0] * hd.EVAL_EPISODES and row["still_up_at_end"] == 0


def test_a_missing_checkpoint_names_the_command_that_makes_it(tmp_path):
    with pytest.raises(SystemExit, match="paper_tables.py"):
        hd.main(["--runs", str(tmp_path), "--seeds", "0"])
