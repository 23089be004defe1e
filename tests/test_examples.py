"""The main example end to end: a (shortened) --quick run writes every artefact and results.json has
the documented fields (resume itself is tested on the same host loop in test_optim)."""

import json
import os
import subprocess
import sys

from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _run(*args, ok=True):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "acrobot_swingup.py"), *args],
                          capture_output=True, text=True, env=env, timeout=900)
    assert (proc.returncode == 0) == ok, proc.stderr[-3000:]
    return proc


def test_help():
    out = _run("--help").stdout
    for flag in ("--seed", "--iterations", "--out", "--resume", "--quick", "--bodies"):
        assert flag in out


def test_quick_run_writes_every_artefact(tmp_path):
    out = tmp_path / "run"
    _run("--quick", "--iterations", "1", "--out", str(out), "--seed", "3", "--no-progress")
    for name in ("checkpoint.eqx", "results.json", "learning_curve.png", "swingup.png", "swingup.gif"):
        assert (out / name).stat().st_size > 0, name
    res = json.loads((out / "results.json").read_text())
    for field in ("return", "balanced", "env_steps", "wall_clock_seconds", "seed", "config"):
        assert field in res, field
    assert res["seed"] == 3 and res["iterations"] == 1
    assert res["config"]["algorithm"] == "CEAPGConfig" and res["config"]["task"] == "acrobot"
    cfg = res["config"]
    assert res["env_steps"] == cfg["num_candidates"] * cfg["apg_steps"] * cfg["episodes"] * cfg["horizon"]
    assert isinstance(res["balanced"], bool)
    # the shipped policy is chosen on selection episodes, not on the reported ones
    assert set(res["selection_returns"]) == {"best", "mean"}
    assert res["policy"] == max(res["selection_returns"], key=res["selection_returns"].get)
    assert res["return"] == res["returns_by_policy"][res["policy"]]
    assert -5000 < res["return"] <= 5000
    gif = Image.open(out / "swingup.gif")
    assert gif.n_frames > 50  # the 5-s episode, one frame per 0.05 s
    assert Image.open(out / "swingup.png").size[0] > 300
    # resuming with another seed (or more iterations done than asked) is refused in one line, not a traceback
    err = _run("--quick", "--iterations", "1", "--out", str(out), "--seed", "4", "--resume", "--no-progress",
               ok=False).stderr
    assert "cannot resume" in err and "seed" in err and "Traceback" not in err
    # --bodies reaches the config: the rods' checkpoint is refused for the Brax v1 bodies, naming the field
    err = _run("--quick", "--iterations", "1", "--out", str(out), "--seed", "3", "--resume", "--bodies", "brax_v1",
               "--no-progress", ok=False).stderr
    assert "cannot resume" in err and "bodies" in err and "brax_v1" in err and "Traceback" not in err
    assert not (out / "results.json.tmp").exists()  # results.json is written through a temporary file


def test_shac_example_runs_and_writes_its_results(tmp_path):
    """examples/shac_cartpole.py end to end on two epochs (it once crashed at its evaluation: the SHAC cartpole
    lacked the ``first_pole`` that ``balanced`` reads)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "shac_cartpole.py"), "--epochs", "2",
                           "--eval-every", "1", "--out", str(tmp_path), "--no-progress"],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["epochs"] == 2 and res["eval_episodes"] == 16 and 0.0 <= res["balanced_fraction"] <= 1.0
    assert res["env_steps"] == 2 * res["config"]["num_envs"] * res["config"]["short_horizon"]  # epochs x envs x h
    assert (tmp_path / "learning_curve.png").stat().st_size > 0
