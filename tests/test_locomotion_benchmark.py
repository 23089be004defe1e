"""``benchmarks/locomotion.py`` without training: a budget in env steps becomes whole epochs and a killed run resumes,
the table and plots come from the run files, a fresh clone's runs are restored from the published JSON, and a bad
budget is refused by name."""

import json

import pytest

from benchmarks import locomotion
from benchmarks._cli import restore_runs, run_file


def _record(algo, task, seed, ret, curve):
    return {"algo": algo, "task": task, "seed": seed, "return": ret, "return_std": 10.0, "env_steps": curve[-1][0],
            "wall_clock": curve[-1][1], "curve": curve, "config": {}}


def test_a_bptt_budget_is_whole_epochs_and_a_checkpoint_is_resumed(tmp_path, monkeypatch):
    seen = {}

    def fake_main(title, out, make_task, cfg, quick, argv, actor_units):
        seen.update(title=title, iterations=cfg.iterations, argv=argv, units=actor_units)
        return {"return": 1.0, "return_std": 0.0, "env_steps": 0.0, "wall_clock_s": 0.0, "config": {},
                "curve": [{"env_steps": 0.0, "elapsed": 0.0, "return": 1.0}]}

    monkeypatch.setattr(locomotion, "locomotion_main", fake_main)
    locomotion.run_differentiable("bptt", "ant", 0, tmp_path, steps=32_001)  # 32 envs x 1000 steps per epoch
    assert seen["iterations"] == 2 and "--resume" not in seen["argv"] and seen["title"] == "BPTT on ant"
    (tmp_path / "bptt_humanoid_1").mkdir()
    (tmp_path / "bptt_humanoid_1" / "checkpoint.eqx").write_bytes(b"")
    locomotion.run_differentiable("bptt", "humanoid", 1, tmp_path)
    assert seen["iterations"] == 2000 and "--resume" in seen["argv"] and seen["units"] == (256, 128)


def test_ppo_on_a_3d_task_trains_in_a_child_with_the_ynn_flag_and_a_planar_one_in_process(tmp_path, monkeypatch):
    """Brax's trainer jits its own programs: a 3-D task's PPO runs in a fresh interpreter whose XLA_FLAGS hold
    ``YNN_OFF_FLAG`` (unless this one's do), which writes the run file; the planar hopper's runs here."""
    children, in_process = [], []

    def fake_child(argv, env, cwd, check):
        children.append((argv, env["XLA_FLAGS"]))
        run_file(tmp_path, "ppo", "ant", 3).write_text(json.dumps(_record("ppo", "ant", 3, 5.0, [[0, 0, 5.0]])))

    def fake_ppo(task, seed, steps):
        in_process.append(task)
        return {k: v for k, v in _record("ppo", task, seed, 7.0, [[0, 0, 7.0]]).items() if k not in ("algo", "task")}

    monkeypatch.delenv("XLA_FLAGS", raising=False)
    monkeypatch.setattr(locomotion.subprocess, "run", fake_child)
    monkeypatch.setattr(locomotion, "run_ppo", fake_ppo)
    assert locomotion.train_one("ppo", "ant", 3, tmp_path, ppo_steps=1000)["return"] == 5.0
    (argv, flags), = children
    assert flags == locomotion.YNN_OFF_FLAG and argv[-2:] == ["--ppo-steps", "1000"] and "ant" in argv
    assert locomotion.train_one("ppo", "hopper", 0, tmp_path)["return"] == 7.0 and in_process == ["hopper"]
    monkeypatch.setenv("XLA_FLAGS", locomotion.YNN_OFF_FLAG)  # the child itself: trains in its own process
    assert locomotion.train_one("ppo", "ant", 4, tmp_path)["return"] == 7.0 and in_process == ["hopper", "ant"]
    assert len(children) == 1


def test_the_table_and_plots_come_from_the_run_files_and_restore_on_a_fresh_clone(tmp_path):
    runs_dir, out = tmp_path / "runs", tmp_path / "results"
    runs_dir.mkdir(), out.mkdir()
    records = [_record("shac", "ant", 0, 8000.0, [[0, 0, 100.0], [4.1e6, 1300.0, 8000.0]]),
               _record("shac", "ant", 1, 8400.0, [[0, 0, 120.0], [2e6, 600.0, 8500.0], [4.1e6, 1200.0, 8400.0]]),
               _record("ppo", "ant", 0, 1681.0, [[0, 0, 50.0], [1.7e7, 4330.0, 1681.0]])]
    for r in records:
        run_file(runs_dir, r["algo"], r["task"], r["seed"]).write_text(json.dumps(r))
    runs = locomotion.load_runs(runs_dir)
    assert list(runs) == ["ant"] and list(runs["ant"]) == ["shac", "ppo"]
    locomotion.write_table(runs, out)
    rows = json.loads((out / "locomotion.json").read_text())["rows"]
    shac, ppo = rows
    assert shac["return"] == "8200 +- 200" and shac["per seed"] == "8000, 8400" and shac["seeds"] == 2
    assert shac["best evaluation on the way"] == "8000, 8500" and shac["published"] == "7660"
    assert ppo["algorithm"] == "Brax PPO" and ppo["published"] == "6605" and ppo["env steps"] == "1.7e+07"
    assert "| ant | SHAC | 2 | 8200 +- 200 |" in (out / "locomotion.md").read_text()
    locomotion.plot_task("ant", runs["ant"], tmp_path / "ant.png")
    assert (tmp_path / "ant.png").read_bytes()[:4] == b"\x89PNG"
    fresh = tmp_path / "fresh"
    restore_runs(fresh, out / "locomotion.json", locomotion.published_runs)
    assert locomotion.load_runs(fresh) == runs


@pytest.mark.parametrize("flag", ["--bptt-steps", "--ppo-steps"])
def test_a_budget_below_one_step_is_refused_by_name(flag, capsys):
    with pytest.raises(SystemExit):
        locomotion.main([flag, "0", "--tasks", "ant"])
    assert f"{flag} must be >= 1, got 0" in capsys.readouterr().err


def test_a_run_of_some_tasks_keeps_the_other_published_rows(tmp_path):
    """With ``keep``, the published runs it accepts are written back beside the runs the folder already holds (a
    benchmark of one task must not drop the others from the table); a run file already there is not overwritten."""
    published = tmp_path / "locomotion.json"
    records = [_record("shac", "ant", 0, 8000.0, [[0, 0, 100.0]]), _record("shac", "hopper", 0, 4900.0, [[0, 0, 9.0]]),
               _record("ppo", "ant", 0, 1681.0, [[0, 0, 50.0]])]
    published.write_text(json.dumps({"runs": {"ant": {"shac": [records[0]], "ppo": [records[2]]},
                                              "hopper": {"shac": [records[1]]}}}))
    folder = tmp_path / "runs"
    folder.mkdir()
    mine = _record("shac", "ant", 0, 8100.0, [[0, 0, 90.0]])
    run_file(folder, "shac", "ant", 0).write_text(json.dumps(mine))
    restore_runs(folder, published, locomotion.published_runs, keep=lambda r: r["algo"] != "ppo")
    assert json.loads(run_file(folder, "shac", "ant", 0).read_text()) == mine
    assert json.loads(run_file(folder, "shac", "hopper", 0).read_text()) == records[1]
    assert not run_file(folder, "ppo", "ant", 0).exists()
