"""benchmarks/reverse_curriculum.py: training starts along a balanced swing-up, moved back towards hanging."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks import reverse_curriculum as rc
from benchmarks.swingup_lqr import RESULTS
from lagrange import tasks
from optim import ce_apg


def test_warmup_grows_the_horizon_at_the_first_frontier():
    assert rc.warmup(120, [100, 300], 6, 500) == [(120, 100, 6), (120, 300, 6), (120, 500, 6)]
    assert rc.warmup(10, [], 1, 500) == [(10, 500, 1)]


def test_a_held_stage_moves_on_a_failed_one_halves_the_move():
    assert rc.next_frontier(100, 5, True, 5) == (95, 5)
    assert rc.next_frontier(100, 5, False, 5) == (100, 2)
    assert rc.next_frontier(100, 2, True, 5) == (98, 4)  # grows back after a success, at most the full move
    assert rc.next_frontier(98, 4, True, 5) == (94, 5)
    assert rc.next_frontier(3, 5, True, 5) == (0, 5)  # never past the hanging start
    assert rc.next_frontier(50, 1, False, 5) == (50, 0)  # nothing left to halve: the curriculum stops


def test_stage_starts_weight_the_frontier():
    X = jnp.arange(300.0)[:, None] * jnp.ones((1, 6))
    starts = rc.stage_starts(X, 40, 200, frontier_weight=3)
    k = np.asarray(starts[:, 0]).astype(int)
    assert starts.shape == (3 * 10 + 160, 6) and k.min() == 40 and k.max() == 199
    assert np.sum(k < 50) == 3 * 10 + 10 and np.sum(k >= 50) == 150


def test_controller_states_replay_the_saved_controller():
    task = tasks.double_cartpole()
    d = json.loads((RESULTS / "swingup_lqr_double_cartpole.json").read_text())
    X, ret = rc.controller_states(task, d)
    assert X.shape == (task.horizon + 1, 2 * task.chain.n)
    np.testing.assert_array_equal(np.asarray(X[0]), 0.0)  # the noise-free hanging start
    # the tests run in float64: the float64 re-run the results file records
    assert ret == pytest.approx(d["best"]["return_float64"], rel=1e-9)
    assert bool(tasks.balanced(task, X[:, :task.chain.n]))
    with pytest.raises(SystemExit, match="no balanced controller"):
        rc.controller_states(task, {**d, "best": None})


def test_quick_run_writes_every_stage(tmp_path):
    # --held 0 keeps every stage, so the frontier moves 130 -> 0 in one stage; then the tail on the task's starts
    out = rc.main(["--quick", "--held", "0", "--cpu-devices", "1", "--out", str(tmp_path / "rc.json"),
                   "--checkpoint", str(tmp_path / "rc.eqx")])
    saved = json.loads((tmp_path / "rc.json").read_text())
    assert saved["stages"] == json.loads(json.dumps(out["stages"]))
    assert [r["frontier"] for r in saved["stages"]] == [130, 130, 0, None]
    assert [r["training_horizon"] for r in saved["stages"]] == [100, 500, 500, 500]
    assert [r["iterations"] for r in saved["stages"]] == [1, 2, 3, 4]
    assert saved["stages"][2]["kept"] is True and saved["held_back_to"] == 0
    for r in saved["stages"]:
        assert 0 <= r["frontier_balanced"] <= 16 and 0 <= r["hanging_balanced"] <= 16
        assert np.isfinite(r["hanging_return"])
    # 4 candidates x 2 APG steps x 1 episode x (100 + 3 x 500) steps
    assert saved["env_steps"] == 4 * 2 * 1 * (100 + 3 * 500)
    assert saved["final_hanging_return"] == saved["stages"][-1]["hanging_return"]


@pytest.mark.parametrize("script, frontiers, kept, iterations, held", [
    # the warm-up holds; the move 130 -> 0 fails and is rolled back (the next stage starts again from iteration 2);
    # the half move to 65 holds; --quick stops after two frontier stages, then the tail
    ([16, 16, 0, 16, 5], [130, 130, 0, 65, None], [None, None, False, True, None], [1, 2, 3, 3, 4], 65),
    # the warm-up does not hold: the next stage trains on at the first frontier and is kept; then 130 -> 0 fails
    ([5, 5, 16, 0, 5], [130, 130, 130, 0, None], [None, None, True, False, None], [1, 2, 3, 4, 4], 130),
])
def test_stages_are_kept_or_rolled_back(tmp_path, monkeypatch, script, frontiers, kept, iterations, held):
    """The stage logic with scripted evaluations (frontier episodes balanced per stage, in order)."""
    frontier_balanced = iter(script)
    calls = {"n": 0}

    def scripted(task, policy, norm, key, episodes):  # called frontier first, then hanging, then upright
        calls["n"] += 1
        n = next(frontier_balanced) if calls["n"] % 3 == 1 else 0
        return jnp.zeros(episodes), jnp.arange(episodes) < n

    monkeypatch.setattr(rc, "evaluate", scripted)
    out = rc.main(["--quick", "--cpu-devices", "1", "--out", str(tmp_path / "rc.json"),
                   "--checkpoint", str(tmp_path / "rc.eqx")])
    st = out["stages"]
    assert [r["frontier"] for r in st] == frontiers and [r.get("kept") for r in st] == kept
    assert [r["iterations"] for r in st] == iterations and out["held_back_to"] == held
    trainer, state = ce_apg.load_checkpoint(tmp_path / "rc.eqx")  # the final state, after the tail
    assert int(state.iteration) == iterations[-1] and trainer.config.num_candidates == 4


@pytest.mark.parametrize("argv, flag", [(["--move", "0"], "--move"), (["--last", "100"], "--last"),
                                        (["--last", "900"], "--last"), (["--per-stage", "0"], "--per-stage"),
                                        (["--held", "17"], "--held")])
def test_bad_arguments_name_the_flag(argv, flag):
    with pytest.raises(SystemExit, match=flag):
        rc.main(["--cpu-devices", "1", *argv])
