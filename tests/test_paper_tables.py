"""``benchmarks/paper_tables.py``: ``--set``/``--variant`` run a changed protocol, kept apart from the budget's
tables."""

from __future__ import annotations

import json

import jax
import pytest

from benchmarks import paper_tables as pt
from optim import ce_apg


def test_set_values_parse():
    assert pt.parse_overrides(["warmup_horizons=300,400", "warmup_upright=0", "init_std=0.1", "truncation=none",
                               "normalize=false", "task=cartpole"]) == {
        "warmup_horizons": (300, 400), "warmup_upright": 0, "init_std": 0.1, "truncation": None,
        "normalize": False, "task": "cartpole"}
    with pytest.raises(SystemExit, match="FIELD=VALUE"):
        pt.parse_overrides(["warmup_horizons"])


def test_overrides_are_validated_and_name_the_field():
    cfg = pt.config("ce_apg", "acrobot", "laptop")
    new = pt.with_overrides(cfg, {"warmup_horizons": (300, 400), "warmup_iterations": 20, "warmup_upright": 0})
    assert new == ce_apg.CEAPGConfig.laptop("acrobot", warmup_horizons=(300, 400), warmup_iterations=20,
                                            warmup_upright=0.0)
    with pytest.raises(ValueError, match="no field warmup_horizon;.*warmup_horizons"):
        pt.with_overrides(cfg, {"warmup_horizon": (300,)})
    with pytest.raises(ValueError, match="num_elites"):
        pt.with_overrides(cfg, {"num_elites": 30})


def test_variant_runs_and_tables_are_kept_apart(tmp_path):
    with pytest.raises(SystemExit, match="--variant"):
        pt.main(["--budget", "smoke", "--set", "episodes=2"])
    out, results = tmp_path / "runs", tmp_path / "results"
    devices = str(len(jax.devices("cpu")))  # JAX has started in this process: keep its device count
    pt.main(["--budget", "smoke", "--tasks", "cartpole", "--algos", "ce_apg", "--seeds", "0", "--variant", "two",
             "--set", "episodes=2", "--out", str(out), "--results", str(results), "--no-progress",
             "--cpu-devices", devices])
    run = json.loads((out / "smoke_two" / "ce_apg_cartpole_0.json").read_text())
    assert run["config"]["episodes"] == 2 and run["env_steps"] == 4 * 2 * 2 * 500 * 2  # K x steps x eps x H x its
    assert not (out / "smoke").exists()
    assert sorted(p.name for p in results.iterdir()) == ["paper_tables_smoke_two_results.json",
                                                         "paper_tables_smoke_two_tables.md"]
    assert "variant `two`: `episodes=2`" in (results / "paper_tables_smoke_two_tables.md").read_text()


def test_a_fresh_out_folder_restores_the_published_runs(tmp_path):
    """runs/ is not in git: on a fresh clone the published runs come back and are not retrained."""
    results = tmp_path / "results"
    results.mkdir()
    published = [{"algo": "ce_apg", "task": "cartpole", "seed": 5, "budget": "smoke", "return": -1.0, "balanced": True,
                  "balanced_fraction": 1.0, "env_steps": 1.0, "wall_clock_seconds": 1.0, "config": {}}]
    (results / "paper_tables_smoke_results.json").write_text(json.dumps(published))
    out = tmp_path / "runs"
    pt.main(["--budget", "smoke", "--tasks", "cartpole", "--algos", "ce_apg", "--seeds", "5", "--out", str(out),
             "--results", str(results), "--no-progress", "--cpu-devices", str(len(jax.devices("cpu")))])
    assert json.loads((out / "smoke" / "ce_apg_cartpole_5.json").read_text()) == published[0]  # not retrained
    table = json.loads((results / "paper_tables_smoke_results.json").read_text())
    assert table == published


def test_unknown_set_field_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exit_info:
        pt.main(["--budget", "smoke", "--algos", "ce_apg", "--variant", "x", "--set", "warmup_horizon=300",
                 "--cpu-devices", str(len(jax.devices("cpu")))])
    assert exit_info.value.code == 2  # argparse's usage error, before any training
    assert "no field warmup_horizon;" in capsys.readouterr().err


def test_a_finished_run_of_another_config_is_not_tabled_as_this_one(tmp_path):
    cfg = pt.config("ce_apg", "acrobot", "laptop")
    saved = json.loads(json.dumps(pt.apg.config_to_dict(cfg)))
    pt.check_same_config("run.json", saved, cfg)  # the same protocol: reused
    old = dict(saved, iterations=saved["iterations"] + 1, apg_steps=saved["apg_steps"] - 1)
    with pytest.raises(SystemExit, match=r"run.json was trained with another config \(apg_steps: run .*iterations"):
        pt.check_same_config("run.json", old, cfg)
    # a field added to the config class after the run was saved counts as unchanged while it has its default
    pt.check_same_config("run.json", {k: v for k, v in saved.items() if k != "warmup_upright"}, cfg)
    with pytest.raises(SystemExit, match="warmup_upright"):
        pt.check_same_config("run.json", {k: v for k, v in saved.items() if k != "warmup_upright"},
                             pt.with_overrides(cfg, {"warmup_upright": 0.25}))
    # and one_run refuses to reuse it
    (tmp_path / "ce_apg_acrobot_0.json").write_text(json.dumps({"return": 1.0, "config": old}))
    with pytest.raises(SystemExit, match="another config"):
        pt.one_run("ce_apg", "acrobot", 0, "laptop", cfg, str(tmp_path), progress=False)


def test_result_files_are_written_whole(tmp_path):
    from benchmarks._files import write_json

    path = tmp_path / "r.json"
    path.write_text('{"old": true}')
    write_json(path, {"new": [1, 2]})
    assert json.loads(path.read_text()) == {"new": [1, 2]}
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]  # no temporary file left beside it


def test_the_apg_footnote_only_under_a_table_with_apg():
    """The note on the APG row's paper column ("Brax's APG") is printed only where the table has an APG row."""
    row = {"task": "acrobot", "return": 1.0, "balanced": False, "balanced_fraction": 0.0, "env_steps": 10,
           "wall_clock_seconds": 1.0}
    assert pt.PAPER_NOTE["apg"] not in pt.table([{**row, "algo": "ce_apg"}], "laptop")
    assert pt.PAPER_NOTE["apg"] in pt.table([{**row, "algo": "ce_apg"}, {**row, "algo": "apg"}], "laptop")
