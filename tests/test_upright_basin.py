"""benchmarks/upright_basin.py: saturated LQR at the top of each swing-up task."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np

from benchmarks import upright_basin as ub
from lagrange import tasks


def test_linearisation_is_unstable_open_loop_and_lqr_stabilises_it():
    task = tasks.acrobot()
    A, B = ub.linearise(task)
    assert A.shape == (4, 4) and B.shape == (4, 1)
    assert np.max(np.abs(np.linalg.eigvals(A))) > 1  # the upright acrobot falls
    K = ub.lqr_gain(A, B, 1e2)
    assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1


def test_the_acrobot_recovers_only_from_a_tiny_lean_the_cartpole_from_a_large_one():
    acro = tasks.acrobot()
    A, B = ub.linearise(acro)
    roll = ub.make_rollout(acro, ub.lqr_gain(A, B, 1e2), 1500)
    x = ub.upright_state(acro)
    assert float(roll(jnp.asarray(x + np.array([0.005, 0, 0, 0], np.float32)))) < 1e-3
    assert float(roll(jnp.asarray(x + np.array([0.2, 0, 0, 0], np.float32)))) > 0.1  # torque saturates: it falls
    cart = tasks.cartpole()
    A, B = ub.linearise(cart)
    roll = ub.make_rollout(cart, ub.lqr_gain(A, B, 1e2), 1500)
    assert float(roll(jnp.asarray(ub.upright_state(cart) + np.array([0, 0.2, 0, 0], np.float32)))) < 1e-3


def test_main_writes_the_result(tmp_path):
    out = tmp_path / "b.json"
    ub.main(["--task", "cartpole", "--r", "100", "--steps", "500", "--out", str(out)])
    d = json.loads(out.read_text())
    row = d["rows"][0]
    assert d["task"] == "cartpole" and row["closed_loop_spectral_radius"] < 1 and set(row["joints"]) == {"1"}


def test_the_brax_v1_acrobot_has_a_wider_basin(tmp_path, monkeypatch):
    """On the authors' Brax v1 bodies (inertia 1 kg m^2) the same LQR recovers from a 0.04 rad lean that the rods'
    acrobot falls from; ``--bodies`` writes its own result file, marked with the bodies."""
    for bodies, recovers in (("rods", False), ("brax_v1", True)):
        task = tasks.make_task("acrobot", bodies)
        A, B = ub.linearise(task)
        roll = ub.make_rollout(task, ub.lqr_gain(A, B, 1e2), 1500)
        err = float(roll(jnp.asarray(ub.upright_state(task) + np.array([0.04, 0, 0, 0], np.float32))))
        assert (err < 1e-3) == recovers, (bodies, err)
    monkeypatch.setattr(ub, "RESULTS", tmp_path)
    ub.main(["--task", "cartpole", "--bodies", "brax_v1", "--r", "100", "--steps", "500"])
    d = json.loads((tmp_path / "upright_basin_cartpole_brax_v1.json").read_text())
    assert d["bodies"] == "brax_v1" and d["rows"][0]["closed_loop_spectral_radius"] < 1
