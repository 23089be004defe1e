"""``benchmarks/balance_horizon.py``: one balance-only CE-APG run, evaluated over its own horizon and over 500 steps."""

from __future__ import annotations

from benchmarks import balance_horizon as bh


def test_one_run_trains_on_upright_starts_and_evaluates_both_lengths():
    r = bh.one("cartpole", 20, 2, 0, warmup=(10,))
    assert r["horizon"] == 20 and r["warmup_horizons"] == [10]
    # the learning curve holds one best-candidate return per iteration: the warm-up's 10 steps, then 20
    curve = r["best_candidate_curve"]
    assert len(curve) == 2
    # cartpole reward is -th^2 <= 0; started upright (th within 0.01 rad) a short episode loses little, far less
    # than hanging (th = pi: -9.87 per step)
    assert -10 * 0.5 < curve[0] <= 0 and -20 * 0.5 < curve[1] <= 0
    assert r["env_steps"] == 24 * 25 * 2 * (10 + 20)
    for at in ("at_training_horizon", "at_500"):
        assert 0.0 <= r[at]["balanced_fraction"] <= 1.0 and "mean_abs_final_x" in r[at]
    assert r["at_training_horizon"]["return"] <= 0 and r["at_500"]["return"] <= 0


def test_config_trains_upright_only():
    """Every training episode starts upright, over the given warm-up or none (whatever the preset has)."""
    flat = bh.config("acrobot", 100, 60)
    assert flat.warmup_horizons == () and flat.upright_starts == 1.0
    assert [flat.training_horizon(i) for i in (0, 59)] == [100, 100]
    cur = bh.config("acrobot", 500, 60, warmup=(100, 200))
    assert (cur.warmup_horizons, cur.warmup_iterations, cur.warmup_upright) == ((100, 200), 20, 1.0)
    assert [cur.training_horizon(i) for i in (0, 20, 40)] == [100, 200, 500]


def test_bodies_reach_the_config_and_the_results_file():
    """``--bodies brax_v1`` trains on the authors' Brax v1 bodies and writes its own results file beside the rods'."""
    assert bh.config("acrobot", 100, 60).bodies == "rods"
    assert bh.config("acrobot", 100, 60, bodies="brax_v1").bodies == "brax_v1"
    assert bh.results_path("acrobot").name == "balance_horizon_acrobot.json"
    assert bh.results_path("acrobot", "brax_v1").name == "balance_horizon_acrobot_brax_v1.json"
