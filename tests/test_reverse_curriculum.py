"""benchmarks/reverse_curriculum.py: training starts along a balanced swing-up, moved back towards hanging."""

from __future__ import annotations

import json

import jax
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
    assert rc.next_frontier(100, 5, True, True, 5) == (95, 5, True)
    assert rc.next_frontier(100, 2, True, False, 5) == (98, 4, True)  # grows back after a success, at most the full
    assert rc.next_frontier(98, 4, True, True, 5) == (94, 5, True)
    assert rc.next_frontier(3, 5, True, True, 5) == (0, 5, True)  # never past the hanging start
    # not held at the new frontier but still at the old one: kept, half the move (at least 1)
    assert rc.next_frontier(100, 5, False, True, 5) == (100, 2, True)
    assert rc.next_frontier(100, 1, False, True, 5) == (100, 1, True)
    # held nowhere: rolled back, half the move; halved to 0, the next stage trains at the frontier itself
    assert rc.next_frontier(100, 5, False, False, 5) == (100, 2, False)
    assert rc.next_frontier(50, 1, False, False, 5) == (50, 0, False)


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
    with pytest.raises(SystemExit, match="found on the 'rods' bodies, the task is on 'brax_v1'"):
        rc.controller_states(tasks.make_task("double_cartpole", "brax_v1"), d)


@pytest.mark.parametrize("task, bodies", [("double_cartpole", "rods"),
                                          # the acrobot's preset observes (sin, cos, velocities): the evaluation too
                                          ("acrobot", "brax_v1")])
def test_quick_run_writes_every_stage(tmp_path, task, bodies):
    # --held 0 keeps every stage, so the frontier moves 130 -> 0 in one stage; then the tail on the task's starts
    out = rc.main(["--quick", "--held", "0", "--cpu-devices", "1", "--out", str(tmp_path / "rc.json"),
                   "--checkpoint", str(tmp_path / "rc.eqx"), "--task", task, "--bodies", bodies])
    saved = json.loads((tmp_path / "rc.json").read_text())
    assert saved["task"] == task and saved.get("bodies", "rods") == bodies and saved["config"]["bodies"] == bodies
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
    # (balanced from the new frontier, from the previous one) per stage, in order. The warm-up holds; the move
    # 130 -> 0 loses the hold everywhere and is rolled back (the next stage starts again from iteration 2); the half
    # move to 65 holds; --quick stops after two frontier stages, then the tail
    ([16, 16, (0, 0), (16, 16), 5], [130, 130, 0, 65, None], [None, None, False, True, None], [1, 2, 3, 3, 4], 65),
    # the move 130 -> 0 fails there but still holds at 130: kept, and the next try (65) starts from iteration 3
    ([16, 16, (0, 16), (16, 16), 5], [130, 130, 0, 65, None], [None, None, True, True, None], [1, 2, 3, 4, 5], 65),
    # the warm-up does not hold: the next stage trains on at the first frontier and is kept; then 130 -> 0 fails
    ([5, 5, 16, (0, 0), 5], [130, 130, 130, 0, None], [None, None, True, False, None], [1, 2, 3, 4, 4], 130),
])
def test_stages_are_kept_or_rolled_back(tmp_path, monkeypatch, script, frontiers, kept, iterations, held):
    _scripted_run(tmp_path, monkeypatch, script, frontiers, kept, iterations, held, ["--quick"])


def test_a_move_halved_to_nothing_consolidates_at_the_frontier(tmp_path, monkeypatch):
    # --move 2: 130 -> 128 and 130 -> 129 lose the hold everywhere (rolled back); the move is 0, so the next stage
    # trains at 130 itself (kept: it holds there); then 130 -> 129 holds
    script = [16, 16, (0, 0), (0, 0), 16, (16, 16), 5]
    _scripted_run(tmp_path, monkeypatch, script, [130, 130, 128, 129, 130, 129, None],
                  [None, None, False, False, True, True, None], [1, 2, 3, 3, 3, 4, 5], 129,
                  ["--first", "130", "--move", "2", "--per-stage", "1", "--horizons", "100", "--max-stages", "4",
                   "--tail", "1"])


def _scripted_run(tmp_path, monkeypatch, script, frontiers, kept, iterations, held, argv):
    """The stage logic with scripted evaluations and a trainer that only counts iterations."""
    results = iter(script)

    def scripted(task, X, frontier, previous, policy, norm, key):
        r = next(results)
        new, old = r if isinstance(r, tuple) else (r, None)
        assert (previous is None) == (old is None)  # the old frontier is evaluated on frontier stages only
        out = {f"{k}_{v}": 0 for k in ("frontier", "hanging", "upright") for v in ("return", "balanced")}
        out["frontier_balanced"] = new
        if previous is not None:
            out["previous_frontier_balanced"] = old
        return out

    real = rc.ce_apg.make_trainer

    def untrained(config, task):  # the real trainer, but an iteration only counts (no compile, no training)
        trainer = real(config, task)
        return trainer._replace(update=lambda st: (st._replace(iteration=st.iteration + 1), {"best_return": 0.0}))

    monkeypatch.setattr(rc, "evaluate_stage", scripted)
    monkeypatch.setattr(rc.ce_apg, "make_trainer", untrained)
    out = rc.main(["--cpu-devices", "1", "--out", str(tmp_path / "rc.json"), "--checkpoint", str(tmp_path / "rc.eqx"),
                   *argv])
    st = out["stages"]
    assert [r["frontier"] for r in st] == frontiers and [r.get("kept") for r in st] == kept
    assert [r["iterations"] for r in st] == iterations and out["held_back_to"] == held
    trainer, state = ce_apg.load_checkpoint(tmp_path / "rc.eqx")  # the final state, after the tail
    assert int(state.iteration) == iterations[-1] and trainer.config.task == "double_cartpole"
    assert out["finished"] and json.loads((tmp_path / "rc.json").read_text())["stages"] == json.loads(json.dumps(st))


def test_stage_evaluation_counts_balanced_episodes_from_each_place():
    """On the all-zero CE mean (no force at all) the counts and the hanging return are known: it balances from
    nowhere, and from hanging the chain stays down."""
    task = tasks.double_cartpole()
    d = json.loads((RESULTS / "swingup_lqr_double_cartpole.json").read_text())
    X, _ = rc.controller_states(task, d)
    cfg = ce_apg.CEAPGConfig.laptop("double_cartpole")
    trainer = ce_apg.make_trainer(cfg)
    policy, norm = trainer.policy(trainer.init(jax.random.PRNGKey(0)), "mean")
    r = rc.evaluate_stage(task, X, 120, 125, policy, norm, jax.random.PRNGKey(1))
    assert set(r) == {f"{k}_{v}" for k in ("frontier", "previous_frontier", "hanging", "upright")
                      for v in ("return", "balanced")}
    assert r["hanging_balanced"] == 0 and r["upright_balanced"] == 0 and r["frontier_balanced"] == 0
    # the all-zero policy pushes nothing: from hanging (+-0.01) the chain stays near hanging, 10 - pi^2 per step
    assert r["hanging_return"] == pytest.approx(500 * (10 - np.pi**2), abs=10.0)


@pytest.mark.parametrize("argv, flag", [(["--move", "0"], "--move"), (["--last", "100"], "--last"),
                                        (["--last", "900"], "--last"), (["--per-stage", "0"], "--per-stage"),
                                        (["--held", "17"], "--held"),
                                        # no double-cartpole controller on the Brax v1 bodies: --bodies picks the file
                                        (["--bodies", "brax_v1"], r"swingup_lqr_double_cartpole_brax_v1.json does "
                                                                  r"not exist \(--controller\)")])
def test_bad_arguments_name_the_flag(argv, flag):
    with pytest.raises(SystemExit, match=flag):
        rc.main(["--cpu-devices", "1", *argv])
