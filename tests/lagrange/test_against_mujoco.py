"""lagrange against MuJoCo C on the same model, exported by :func:`lagrange.interop.mjcf.to_mjcf`.

Throughout, the error of ``a`` against a reference ``b`` is

    rel(a, b) = max|a - b| / max(1, max|b|)

(the largest error relative to the reference's largest entry, absolute below 1).

- Mass matrix (``mj_fullM``), bias forces (``qfrc_bias``; MuJoCo keeps joint damping apart in
  ``qfrc_passive``) and accelerations (``qacc`` after ``mj_forward``) agree to 1e-10: each is a
  few dozen float64 operations on O(1) numbers, so the two codes differ by ~1e-15 (times the
  conditioning of ``M`` for ``qacc``); measured <= 1.4e-12, the largest where a zero moment of
  inertia exported as ``tiny = 1e-12`` rotates (see :mod:`lagrange.interop.mjcf`).
- 500-step trajectories agree to 1e-9: ``lg.SemiImplicitEuler()`` against MuJoCo's
  ``integrator="Euler"`` and ``lg.RK4()`` against ``integrator="RK4"``. Both pairs compute the
  same recurrence, so they differ only by round-off (1e-16 per step) accumulated over 500 steps
  and amplified by the flow's sensitivity (small here: hanging starts, bounded random controls).
- Chains: the catalogue systems and seeded random chains of 2-8 links with mixed revolute and
  prismatic joints (at any depth, including a slide joint below a hinge, which Brax gets wrong;
  see ``test_against_brax.py``), random axes, centres of mass, inertias, damping, armature and
  gears.

The helpers (``seeded_chain``, ``mujoco_model``, ``mujoco_batch_rollout``, ``rel``, ``CHAINS``) are in
``tests/helpers.py``, shared with ``test_against_brax.py`` and ``interop/test_mjcf.py`` (the export's own
structural checks: the MJCF it writes and the parameters MuJoCo compiles from it).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.planar.lower import lower as planar
from tests.helpers import (
    CHAINS,
    TRAJECTORY,
    has_slide_below_hinge,
    mujoco_model,
    mujoco_batch_rollout,
    random_problem,
    rel,
    seeded_chain,
)

EXACT = 1e-10  # single evaluations: M, bias forces, qacc


@jax.jit
def _simulate_jit(chain, q0, qd0, us, dt, solver):
    tr = lg.simulate(chain, q0, qd0, us, dt, solver, check=False)
    return tr.q[1:], tr.qd[1:]


def simulate(chain, q0, qd0, us, dt, solver):
    """lg.simulate, jitted once per chain structure and solver (dt is traced); returns q, qd after each step."""
    q, qd = _simulate_jit(chain, jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us), jnp.asarray(dt), solver)
    return np.asarray(q), np.asarray(qd)


def test_random_chains_cover_the_structures():
    """The seeded chains really mix joints at every depth, damping, armature and gears."""
    chains = [seeded_chain(seed) for seed in range(10)]
    lowered = [planar(c) for c in chains]
    assert {c.nv for c in chains} == set(range(2, 9))
    assert any(has_slide_below_hinge(c) for c in chains)
    assert any(p.joints[0] == "prismatic" for p in lowered)
    assert any(any(a != 0.0 for a in p.axes) for p in lowered)
    assert any(p.damping is not None for p in lowered) and any(p.armature is not None for p in lowered)
    assert all(c.m >= 1 for c in chains) and any(c.m >= 2 for c in chains)


# --- kinematics -----------------------------------------------------------------------------


@pytest.mark.parametrize("chain, dt", CHAINS[:4] + CHAINS[4:8])
def test_kinematics_match_mujoco(chain, dt):
    """Joint origins (MuJoCo ``xpos``) match ``lg.positions`` in the x-z plane."""
    model, data = mujoco_model(chain, dt)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q = rng.uniform(-2, 2, chain.nv)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        ours = np.asarray(lg.positions(chain, jnp.asarray(q)))  # each body's origin: its joint's, (x, 0, z)
        assert rel(data.xpos[1:, [0, 2]], ours[:, ::2]) <= EXACT
        assert np.all(data.xpos[1:, 1] == 0.0)


# --- dynamics ---------------------------------------------------------------------------------


@pytest.mark.parametrize("chain, dt", CHAINS)
def test_dynamics_match_mujoco(chain, dt):
    """M (mj_fullM), bias forces (qfrc_bias + damping) and qacc (mj_forward) to 1e-10."""
    model, data = mujoco_model(chain, dt)
    rng = np.random.default_rng(0)
    lowered = planar(chain)
    damping = np.zeros(chain.nv) if lowered.damping is None else np.asarray(lowered.damping)
    q, qd = rng.uniform(-3, 3, (5, chain.nv)), rng.uniform(-3, 3, (5, chain.nv))
    u = rng.uniform(-2, 2, (5, chain.m))
    # vmapped and compiled once per chain: op-by-op (eager) evaluation of the recursive algorithms' scans costs
    # ~3x their compilation (4-8 links); below RECURSIVE_MIN links either costs a fraction of a second
    M, bias, qdd = jax.jit(jax.vmap(
        lambda q, qd, u: (lg.mass_matrix(chain, q), lg.bias_forces(chain, q, qd), lg.forward_dynamics(chain, q, qd, u))
    ))(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u))
    for k in range(5):
        data.qpos[:], data.qvel[:], data.ctrl[:] = q[k], qd[k], u[k]
        mujoco.mj_forward(model, data)
        M_mj = np.zeros((chain.nv, chain.nv))
        mujoco.mj_fullM(model, data, M_mj)
        assert rel(M[k], M_mj) <= EXACT
        assert rel(bias[k], data.qfrc_bias - data.qfrc_passive) <= EXACT
        assert rel(-damping * qd[k], data.qfrc_passive) <= EXACT
        assert rel(qdd[k], data.qacc) <= EXACT


# --- trajectories -----------------------------------------------------------------------------


@pytest.mark.parametrize("chain, dt", CHAINS)
def test_semi_implicit_euler_matches_mujoco_euler(chain, dt):
    """500 steps of lg.SemiImplicitEuler() against MuJoCo's Euler (implicit damping) to 1e-9."""
    q0, qd0, us = random_problem(chain, 7)
    model, data = mujoco_model(chain, dt, "Euler")
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)
    q, qd = simulate(chain, q0, qd0, us, dt, lg.SemiImplicitEuler())
    assert rel(q, q_mj[0]) <= TRAJECTORY
    assert rel(qd, qd_mj[0]) <= TRAJECTORY
    if planar(chain).damping is not None:
        # the test sees the implicit damping: with MuJoCo's eulerdamp off the trajectories part
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_EULERDAMP
        q_explicit, _ = mujoco_batch_rollout(model, data, q0, qd0, us)
        assert rel(q_explicit[0], q_mj[0]) > 1e3 * TRAJECTORY


# RK4 compiles ~3x slower than SemiImplicitEuler: the catalogue and three random chains
# (2, 5 and 8 links, each with a slide joint below a hinge) keep the suite's budget.
RK4_CHAINS = CHAINS[:4] + [c for c in CHAINS if c.id in ("random7", "random3", "random6")]


@pytest.mark.parametrize("chain, dt", RK4_CHAINS)
def test_rk4_matches_mujoco_rk4(chain, dt):
    """500 steps of lg.RK4() against MuJoCo's RK4 integrator to 1e-9.

    MuJoCo's RK4 is the classic four-stage method on (qpos, qvel) with ctrl held constant over the
    step and damping explicit (in qfrc_passive), i.e. classic RK4 on the full ODE.
    """
    q0, qd0, us = random_problem(chain, 8)
    model, data = mujoco_model(chain, dt, "RK4")
    q_mj, qd_mj = mujoco_batch_rollout(model, data, q0, qd0, us)
    q, qd = simulate(chain, q0, qd0, us, dt, lg.RK4())
    assert rel(q, q_mj[0]) <= TRAJECTORY
    assert rel(qd, qd_mj[0]) <= TRAJECTORY
    # the tolerance tells integrators apart: MuJoCo's own Euler lands far from its RK4
    model_euler, data_euler = mujoco_model(chain, dt, "Euler")
    q_euler, _ = mujoco_batch_rollout(model_euler, data_euler, q0, qd0, us)
    assert rel(q_euler[0], q_mj[0]) > 1e3 * TRAJECTORY
