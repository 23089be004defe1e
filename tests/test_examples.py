"""The examples: on the public API only and one screen long; the main example end to end (a shortened --quick run
writes every artefact and results.json has the documented fields; resume itself is tested on the same host loop in
test_optim); every swing-up example offers the driver's flags; the SHAC example end to end.

The ``--help`` texts of the examples come from one fresh interpreter that runs each example script as ``__main__``
(``runpy``, the script's own ``sys.argv`` and ``sys.path[0]``, as ``python examples/NAME.py --help`` would), instead of
one interpreter per example: the same code path, one interpreter start instead of six."""

import ast
import json
import os
import runpy
import subprocess
import sys
import textwrap
import warnings

import jax
import pytest
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = sorted(f for f in os.listdir(os.path.join(ROOT, "examples")) if f.endswith(".py"))
SWINGUPS = ("acrobot_swingup.py", "cartpole_swingup.py", "double_cartpole_swingup.py", "custom_chain.py")
MAX_LINES = 80


def violations(source: str) -> list[str]:
    """What keeps ``source`` from being an example: a ``sys.path`` use, a relative import, an import of a private
    name (a part starting with ``_``, ``__future__`` aside) or from ``benchmarks``/``research``, more than 80 lines."""
    found = []
    if len(source.splitlines()) > MAX_LINES:
        found.append(f"{len(source.splitlines())} lines > {MAX_LINES}")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and node.attr == "path" and getattr(node.value, "id", None) == "sys":
            found.append(f"line {node.lineno}: sys.path")
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                found.append(f"line {node.lineno}: relative import")
            if node.module == "__future__":
                continue
            names = [f"{node.module}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] in ("benchmarks", "research") or any(part.startswith("_") for part in parts):
                found.append(f"line {node.lineno}: import {name}")
    return found


def test_examples_use_the_public_api_only_and_fit_one_screen():
    assert len(EXAMPLES) >= 6 and set(SWINGUPS) <= set(EXAMPLES), EXAMPLES
    for name in EXAMPLES:
        with open(os.path.join(ROOT, "examples", name)) as f:
            assert violations(f.read()) == [], name


def test_the_example_check_finds_each_violation():
    bad = "import sys\nsys.path.insert(0, '.')\nfrom optim._loop import run\nimport benchmarks.throughput\n" \
          "from research import LOG\nfrom . import x\nfrom optim import _private\n" + "pass\n" * 80
    found = violations(bad)
    for what in ("sys.path", "optim._loop.run", "benchmarks.throughput", "research.LOG", "relative import",
                 "optim._private", "87 lines"):
        assert any(what in v for v in found), (what, found)
    assert violations("from __future__ import annotations\nimport optim\nfrom optim.cli import swingup_main\n") == []


def _run(*args, ok=True, example="acrobot_swingup.py"):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "examples", example), *args],
                          capture_output=True, text=True, env=env, timeout=900)
    assert (proc.returncode == 0) == ok, proc.stderr[-3000:]
    return proc


# the examples whose --help the tests read
HELPED = (*SWINGUPS, "mjcf_import.py", "cheetah_shac.py", "ant_shac.py", "humanoid_shac.py", "snu_humanoid_shac.py")

# Each example run as `python examples/NAME.py --help` runs it: as __main__, with its own argv and its folder first
# on sys.path (not the working directory), in a fresh interpreter (one for all of them, the modules imported once).
_HELP = textwrap.dedent(
    """
    import contextlib, io, json, os, runpy, sys
    out = {}
    for path in sys.argv[1:]:
        sys.argv, sys.path[0] = [path, "--help"], os.path.dirname(path)
        text = io.StringIO()
        try:
            with contextlib.redirect_stdout(text):
                runpy.run_path(path, run_name="__main__")
            code = "returned without exiting"
        except SystemExit as exit:
            code = exit.code
        out[os.path.basename(path)] = {"code": code, "stdout": text.getvalue()}
    print(json.dumps(out))
    """
)


@pytest.fixture(scope="module")
def help_texts():
    """``{example: its --help text}`` for every example of ``HELPED``, each of which exited with status 0."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-c", _HELP, *(os.path.join(ROOT, "examples", e) for e in HELPED)],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    runs = json.loads(proc.stdout.strip().splitlines()[-1])
    assert {name: run["code"] in (0, None) for name, run in runs.items()} == dict.fromkeys(HELPED, True), \
        (runs, proc.stderr[-3000:])
    return {name: run["stdout"] for name, run in runs.items()}


@pytest.mark.parametrize("example", SWINGUPS)
def test_help(example, help_texts):
    out = help_texts[example]
    for flag in ("--seed", "--iterations", "--out", "--resume", "--quick", "--no-progress", "--cpu-devices"):
        assert flag in out, flag
    assert ("--bodies" in out) == (example != "custom_chain.py")  # a chain of one's own has no Brax v1 bodies


def test_mjcf_import_example_help(help_texts):
    out = help_texts["mjcf_import.py"]
    assert "--model" in out and "--seed" in out


def _refusal(*args, example="acrobot_swingup.py") -> str:
    """The one-line message with which ``python examples/EXAMPLE ARGS`` stops, from the example run as ``__main__`` in
    this process (``runpy``, its own ``sys.argv``): the same code path as in a fresh interpreter (the driver raises
    ``SystemExit(message)`` before any training, which Python prints as that line alone, no traceback), in the
    examples' float32 (``jax.enable_x64(False)``: the tests run in float64, and a checkpoint records its task's
    dtypes)."""
    path = os.path.join(ROOT, "examples", example)
    argv = sys.argv
    sys.argv = [path, *args]
    try:
        with jax.enable_x64(False), warnings.catch_warnings(), pytest.raises(SystemExit) as stop:
            # this process's JAX has started: the driver keeps its devices (the refusal comes before any sharding)
            warnings.filterwarnings("ignore", message=r"use_cpu_cores\(\d+\) called after JAX started")
            runpy.run_path(path, run_name="__main__")
    finally:
        sys.argv = argv
    message = stop.value.code
    assert isinstance(message, str) and "\n" not in message, message  # one line, printed as it is
    return message


def test_quick_run_writes_every_artefact(tmp_path):
    """The --quick run of the acrobot example on one iteration, in a fresh interpreter; its two refusals of a resume
    from the example run in this process (``_refusal``)."""
    out = tmp_path / "run"
    _run("--quick", "--iterations", "1", "--out", str(out), "--seed", "3", "--no-progress")
    for name in ("checkpoint.eqx", "results.json", "learning_curve.png", "swingup.png", "swingup.gif"):
        assert (out / name).stat().st_size > 0, name
    res = json.loads((out / "results.json").read_text())
    for field in ("return", "balanced", "env_steps", "wall_clock_seconds", "seed", "config"):
        assert field in res, field
    assert res["seed"] == 3 and res["iterations"] == 1
    assert res["config"]["algorithm"] == "CEAPGConfig" and res["task"] == "acrobot" and res["bodies"] == "rods"
    cfg = res["config"]
    assert res["env_steps"] == cfg["num_candidates"] * cfg["apg_steps"] * cfg["episodes"] * res["horizon"]
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
    err = _refusal("--quick", "--iterations", "1", "--out", str(out), "--seed", "4", "--resume", "--no-progress")
    assert "cannot resume" in err and "seed" in err and "Traceback" not in err
    # --bodies reaches the config: the rods' checkpoint is refused for the Brax v1 bodies, naming the field
    err = _refusal("--quick", "--iterations", "1", "--out", str(out), "--seed", "3", "--resume", "--bodies", "brax_v1",
                   "--no-progress")
    assert "cannot resume" in err and "bodies" in err and "brax_v1" in err and "Traceback" not in err
    assert not (out / "results.json.tmp").exists()  # results.json is written through a temporary file


def test_shac_example_runs_and_writes_its_results(tmp_path):
    """examples/shac_cartpole.py end to end on two epochs (it once crashed at its evaluation: the SHAC cartpole
    lacked the ``first_pole`` that ``balanced`` reads)."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "shac_cartpole.py"), "--iterations", "2",
                           "--eval-every", "1", "--out", str(tmp_path), "--no-progress"],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["epochs"] == 2 and res["eval_episodes"] == 16 and 0.0 <= res["balanced_fraction"] <= 1.0
    assert res["env_steps"] == 2 * res["config"]["num_envs"] * res["config"]["short_horizon"]  # epochs x envs x h
    assert (tmp_path / "learning_curve.png").stat().st_size > 0


def test_locomotion_examples_run_and_write_their_results(tmp_path, help_texts):
    """examples/hopper_shac.py end to end on one epoch (the cheetah's shares the driver: its flags only): every
    artefact, and results.json's documented fields."""
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "hopper_shac.py"), "--quick", "--iterations",
                           "1", "--eval-every", "1", "--out", str(tmp_path), "--no-progress"],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for name in ("checkpoint.eqx", "results.json", "learning_curve.png", "gait.png", "gait.gif"):
        assert (tmp_path / name).stat().st_size > 0, name
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["task"] == "hopper" and res["epochs"] == 1 and res["eval_episodes"] == 16
    assert res["env_steps"] == res["config"]["num_envs"] * res["config"]["short_horizon"]
    assert res["wall_clock_s"] > 0 and res["total_s"] >= res["wall_clock_s"] and res["anchor_return"] == 4800.0
    assert 0.0 <= res["succeeded_fraction"] <= 1.0 and len(res["curve"]) == 2
    for example in ("cheetah_shac.py", "ant_shac.py", "humanoid_shac.py", "snu_humanoid_shac.py"):
        out = help_texts[example]
        for flag in ("--seed", "--iterations", "--out", "--resume", "--quick", "--no-progress", "--overwrite"):
            assert flag in out, (example, flag)


def test_the_quadruped_stands(tmp_path):
    """examples/quadruped_stand.py on its --quick half second: the robot read from URDF with a floating base lands on
    its feet and stands under the position actuators; results.json and the figure."""
    _run("--quick", "--out", str(tmp_path), example="quadruped_stand.py")
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["stood"] and (res["nq"], res["nv"]) == (19, 18) and res["seconds"] == 0.5
    assert 0.2 < res["final_height"] < res["start_height"] and res["final_tilt"] < 0.1
    assert Image.open(tmp_path / "stand.png").size[0] > 300
