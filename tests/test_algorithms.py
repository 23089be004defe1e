"""``benchmarks/algorithms.py --bodies``: runs on the authors' Brax v1 bodies are kept apart from the rods' ones, and a
CE-APG result trained on other bodies is not tabled beside them."""

from __future__ import annotations

import json

import pytest

from benchmarks import algorithms as alg


def _paper_tables_result(folder, bodies):
    """A ``benchmarks/paper_tables.py`` result file as it writes them (the fields ``import_ce_apg`` reads)."""
    folder.mkdir(parents=True, exist_ok=True)
    config = {"task": "acrobot", **({} if bodies is None else {"bodies": bodies})}
    (folder / "ce_apg_acrobot_0.json").write_text(json.dumps(
        {"algo": "ce_apg", "task": "acrobot", "seed": 0, "budget": "laptop", "return": 3000.0, "balanced": False,
         "balanced_fraction": 0.25, "env_steps": 1.8e8, "wall_clock_seconds": 300.0, "config": config}))
    return folder


def test_import_ce_apg_refuses_a_result_of_other_bodies(tmp_path):
    brax = _paper_tables_result(tmp_path / "laptop_braxv1", "brax_v1")
    old = _paper_tables_result(tmp_path / "laptop", None)  # results written before the bodies field: rods
    with pytest.raises(SystemExit, match="bodies='brax_v1', not --bodies rods"):
        alg.import_ce_apg("acrobot", 0, str(brax))
    with pytest.raises(SystemExit, match="bodies='rods', not --bodies brax_v1"):
        alg.import_ce_apg("acrobot", 0, str(old), "brax_v1")
    run = alg.import_ce_apg("acrobot", 0, str(brax), "brax_v1")
    assert (run["return"], run["balanced_fraction"], run["bodies"]) == (3000.0, 0.25, "brax_v1")
    assert "bodies" not in alg.import_ce_apg("acrobot", 0, str(old))  # rods run files stay as they were
    assert alg.import_ce_apg("acrobot", 1, str(brax), "brax_v1") is None


def test_bodies_get_their_own_runs_folder_and_table(tmp_path):
    """``--bodies brax_v1`` reads and writes ``<budget>_brax_v1`` runs and ``algorithms_<budget>_brax_v1`` tables, and
    the table says which bodies; the rods' files are neither read nor touched."""
    src = _paper_tables_result(tmp_path / "laptop_braxv1", "brax_v1")
    runs, out = tmp_path / "runs", tmp_path / "results"
    common = ["--budget", "laptop", "--tasks", "acrobot", "--algos", "ce_apg", "--seeds", "0", "--runs-dir", str(runs),
              "--out", str(out), "--ce-apg-from", str(src)]
    alg.main(common + ["--bodies", "brax_v1"])
    assert sorted(p.name for p in runs.iterdir()) == ["laptop_brax_v1"]
    table = (out / "algorithms_laptop_brax_v1.md").read_text()
    assert "| acrobot | CE-APG | 3000.0 | 1 | 25% | 0% |" in table
    assert "on the tasks' `brax_v1` bodies" in table
    saved = json.loads((out / "algorithms_laptop_brax_v1.json").read_text())
    assert saved["meta"]["bodies"] == "brax_v1"
    assert (out / "algorithms_laptop_brax_v1_acrobot.png").exists()
    assert not (out / "algorithms_laptop.md").exists()
    with pytest.raises(SystemExit, match="not --bodies rods"):  # the rods' table does not take the Brax v1 result
        alg.main(common)
