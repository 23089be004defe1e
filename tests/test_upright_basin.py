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
