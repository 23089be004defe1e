"""``benchmarks/gpu.py`` runs end to end on the CPU at small sizes (``--small``), so that it is ready the day a device
is lent: every section measures every engine it names, records the device and the versions, and writes its JSON and
markdown table. A fresh interpreter, as a user runs it (the script switches JAX's 64-bit mode per table)."""

import json
import os
import subprocess
import sys

from tests.helpers import ROOT


def test_gpu_benchmark_runs_on_the_cpu_at_small_sizes(tmp_path):
    out = tmp_path / "gpu.json"
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-m", "benchmarks.gpu", "--small", "--out", str(out)], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(out.read_text())
    info = res["info"]
    assert info["platform"] == "cpu" and info["versions"]["jax"] and info["versions"]["mujoco"] and res["small"]
    assert list(res["section_s"]) == ["acrobot", "scaling", "legged", "trees3d", "shac", "ppo"]
    rows = res["rows"]
    seen = {(r["section"], r.get("engine"), r.get("kind"), r.get("dtype")) for r in rows}
    for engine in ("lagrange_sie", "lagrange_rk4", "closed_form_rk4"):
        assert ("acrobot", engine, "gradient", "float32") in seen, engine
    for engine in ("mjx_euler", "brax_generalized_sie"):
        assert ("acrobot", engine, "forward", "float32") in seen, engine
    assert ("acrobot", "lagrange_sie", "forward", "float64") in seen
    legged = {r["model"] for r in rows if r["section"] == "legged"}
    assert legged == {"half_cheetah_free_flight", "hopper_on_the_ground"}
    trees = {(r["model"], r["kind"]) for r in rows if r["section"] == "trees3d"}
    assert trees == {("humanoid_free_flight", "forward"), ("half_cheetah_tree", "forward"),
                     ("half_cheetah_tree", "gradient"), ("ant_on_the_ground", "forward")}
    assert all(r["env_steps_per_s"] > 0 and r["first_call_s"] > 0 for r in rows if "env_steps_per_s" in r
               and r["section"] != "shac")
    shac = [r for r in rows if r["section"] == "shac"]
    ppo = [r for r in rows if r["section"] == "ppo"]
    assert len(shac) == 1 and shac[0]["s_per_epoch"] > 0 and shac[0]["epochs"] == 2
    assert len(ppo) == 1 and ppo[0]["env_steps"] > 0 and len(ppo[0]["returns"]) == 16
    table = out.with_suffix(".md").read_text()
    for section in ("## acrobot", "## scaling", "## legged", "## trees3d", "## shac", "## ppo"):
        assert section in table, section
