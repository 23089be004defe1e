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
  see ``test_brax_gradients.py``), random axes, centres of mass, inertias, damping, armature and
  gears.

Helpers here (``random_chain``, ``mujoco_model``, ``mujoco_rollout``, ``rel``) are also used by
``test_brax_gradients.py``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import rollout as mj_rollout_module

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.interop.mjcf import to_mjcf

EXACT = 1e-10  # single evaluations: M, bias forces, qacc
TRAJECTORY = 1e-9  # 500-step trajectories

# Catalogue systems with their physics step from the paper (control dt / substeps).
SYSTEMS = {
    "pendulum": (lambda: lg.systems.pendulum(damping=0.1), 0.01),
    "cartpole": (lg.systems.cartpole, 0.04 / 8),
    "double_cartpole": (lg.systems.double_cartpole, 0.01 / 12),
    "acrobot": (lg.systems.acrobot, 0.01 / 4),
}


def rel(a, b) -> float:
    """max|a - b| / max(1, max|b|)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def random_chain(seed: int, *, slide_below_hinge: bool = True) -> Chain:
    """A seeded random chain of 2-8 links with mixed joints, damping, armature and gears.

    With ``slide_below_hinge=False`` no prismatic joint follows a revolute one (the chains that
    Brax 0.14 simulates correctly).
    """
    rng = np.random.default_rng(seed)
    n = 2 + seed % 7  # seeds 0..6 cover every size from 2 to 8
    specs = []
    seen_revolute = False
    for i in range(n):
        prismatic = rng.random() < (0.5 if i == 0 else 0.3)
        if prismatic and seen_revolute and not slide_below_hinge:
            prismatic = False
        seen_revolute |= not prismatic
        length = float(rng.uniform(0.2, 1.0)) if (not prismatic or rng.random() < 0.5) else 0.0
        specs.append(
            dict(
                joint="prismatic" if prismatic else "revolute",
                mass=float(rng.uniform(0.3, 3.0)),
                length=length,
                com=float(rng.uniform(0.0, 1.0)) * length,
                inertia=float(rng.uniform(0.01, 0.3)) if rng.random() < 0.5 else None,
                axis=float(rng.uniform(-math.pi, math.pi)) if prismatic and rng.random() < 0.5 else 0.0,
                damping=float(rng.uniform(0.05, 1.0)) if rng.random() < 0.5 else 0.0,
                armature=float(rng.uniform(0.01, 0.3)) if rng.random() < 0.4 else 0.0,
                gear=float(abs(rng.choice([-1, 1]) * rng.uniform(0.5, 5.0))) if rng.random() < 0.6 else None,
            )
        )
    if all(spec["gear"] is None for spec in specs):
        specs[0]["gear"] = 1.0
    links = [Link(**spec) for spec in specs]
    return Chain(links, gravity=9.81)


def has_slide_below_hinge(chain: Chain) -> bool:
    first_revolute = chain.joints.index("revolute") if "revolute" in chain.joints else chain.n
    return "prismatic" in chain.joints[first_revolute:]


def mujoco_model(chain: Chain, dt: float, integrator: str = "Euler"):
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=dt, integrator=integrator))
    return model, mujoco.MjData(model)


def mujoco_rollout(model, data, q0, qd0, controls):
    """MuJoCo C ``mj_step`` rollouts (batched over leading dims of q0/qd0/controls).

    q0, qd0: (B, n); controls: (B, T, m). Returns q, qd of shape (B, T, n) after each step.
    """
    q0, qd0, controls = np.atleast_2d(q0), np.atleast_2d(qd0), np.asarray(controls, dtype=float)
    if controls.ndim == 2:
        controls = controls[None]
    batch = max(q0.shape[0], controls.shape[0])
    n = model.nq
    state0 = np.zeros((batch, 1 + 2 * n))
    state0[:, 1 : 1 + n] = q0
    state0[:, 1 + n :] = qd0
    if model.nu == 0:
        controls = np.zeros(controls.shape[:2] + (0,))
    state, _ = mj_rollout_module.rollout(model, data, state0, np.broadcast_to(controls, (batch,) + controls.shape[1:]))
    return state[:, :, 1 : 1 + n], state[:, :, 1 + n :]


def random_problem(chain: Chain, seed: int, steps: int = 500, *, scale=0.3, control_scale=1.0):
    rng = np.random.default_rng(seed)
    q0 = scale * rng.standard_normal(chain.n)
    qd0 = scale * rng.standard_normal(chain.n)
    us = control_scale * rng.standard_normal((steps, chain.m))
    return q0, qd0, us


@jax.jit
def _simulate_jit(chain, q0, qd0, us, dt, solver):
    tr = lg.simulate(chain, q0, qd0, us, dt, solver, check=False)
    return tr.q[1:], tr.qd[1:]


def simulate(chain, q0, qd0, us, dt, solver):
    """lg.simulate, jitted once per chain structure and solver (dt is traced); returns q, qd after each step."""
    q, qd = _simulate_jit(chain, jnp.asarray(q0), jnp.asarray(qd0), jnp.asarray(us), jnp.asarray(dt), solver)
    return np.asarray(q), np.asarray(qd)


def _all_chains():
    out = [pytest.param(make(), dt, id=name) for name, (make, dt) in SYSTEMS.items()]
    out += [pytest.param(random_chain(seed), 0.005, id=f"random{seed}") for seed in range(10)]
    return out


CHAINS = _all_chains()


def test_random_chains_cover_the_structures():
    """The seeded chains really mix joints at every depth, damping, armature and gears."""
    chains = [random_chain(seed) for seed in range(10)]
    assert {c.n for c in chains} == set(range(2, 9))
    assert any(has_slide_below_hinge(c) for c in chains)
    assert any(c.joints[0] == "prismatic" for c in chains)
    assert any(any(a != 0.0 for a in c.axes) for c in chains)
    assert any(c.damping is not None for c in chains) and any(c.armature is not None for c in chains)
    assert all(c.m >= 1 for c in chains) and any(c.m >= 2 for c in chains)


# --- the export -----------------------------------------------------------------------------


def test_export_structure():
    chain = random_chain(3)
    root = ET.fromstring(to_mjcf(chain, timestep=0.002, integrator="RK4", name="demo"))
    assert root.get("model") == "demo"
    assert root.find("compiler").get("inertiafromgeom") == "false"
    opt = root.find("option")
    assert (opt.get("timestep"), opt.get("integrator")) == ("0.002", "RK4")
    assert root.find("custom/numeric").attrib == {"name": "matrix_inv_iterations", "data": "0"}
    joints = root.findall(".//joint")
    assert [j.get("type") for j in joints] == ["hinge" if k == "revolute" else "slide" for k in chain.joints]
    for j in joints:
        if j.get("type") == "hinge":
            assert np.array_equal(np.fromstring(j.get("axis"), sep=" "), [0, -1, 0])
    for g in root.findall(".//geom"):
        assert (g.get("contype"), g.get("conaffinity")) == ("0", "0")
    motors = root.findall("actuator/motor")
    assert [m.get("joint") for m in motors] == [f"q{i}" for i in chain.actuated]
    assert [float(m.get("gear")) for m in motors] == [float(g) for g in chain.gear]
    assert all(m.get("ctrllimited") == "false" for m in motors)


@pytest.mark.parametrize("chain, dt", CHAINS)
def test_model_parameters_round_trip(chain, dt):
    """MuJoCo's compiled model carries exactly the chain's masses, inertias, damping, armature, gears."""
    model, _ = mujoco_model(chain, dt)
    np.testing.assert_array_equal(model.body_mass[1:], np.asarray(chain.mass))
    np.testing.assert_array_equal(model.body_inertia[1:, 1], np.where(chain.inertia > 0, chain.inertia, 1e-12))
    np.testing.assert_array_equal(model.body_ipos[1:, 2], -np.asarray(chain.com))
    damping = np.zeros(chain.n) if chain.damping is None else np.asarray(chain.damping)
    armature = np.zeros(chain.n) if chain.armature is None else np.asarray(chain.armature)
    np.testing.assert_array_equal(model.dof_damping, damping)
    np.testing.assert_array_equal(model.dof_armature, armature)
    np.testing.assert_array_equal(model.actuator_gear[:, 0], np.asarray(chain.gear))
    np.testing.assert_array_equal(model.actuator_trnid[:, 0], chain.actuated)
    assert model.opt.timestep == dt and model.opt.gravity[2] == -float(chain.gravity)


@pytest.mark.parametrize("chain, dt", CHAINS[:4] + CHAINS[4:8])
def test_kinematics_match_mujoco(chain, dt):
    """Joint origins (MuJoCo ``xpos``) match ``lg.positions`` in the x-z plane."""
    model, data = mujoco_model(chain, dt)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q = rng.uniform(-2, 2, chain.n)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        ours = np.asarray(lg.positions(chain, jnp.asarray(q)))[:-1]
        assert rel(data.xpos[1:, [0, 2]], ours) <= EXACT
        assert np.all(data.xpos[1:, 1] == 0.0)


def test_positive_hinge_angle_swings_towards_plus_x():
    chain = lg.systems.pendulum()
    model, data = mujoco_model(chain, 0.01)
    data.qpos[:] = 0.3
    mujoco.mj_kinematics(model, data)
    # the centre of mass at l/2 along d(0.3) = (sin 0.3, -cos 0.3)
    np.testing.assert_allclose(data.xipos[1, [0, 2]], 0.5 * np.array([math.sin(0.3), -math.cos(0.3)]), rtol=0, atol=1e-15)


def test_export_errors():
    chain = lg.systems.cartpole()
    with pytest.raises(ValueError, match="timestep"):
        to_mjcf(chain, timestep=0.0)
    with pytest.raises(ValueError, match="timestep"):
        to_mjcf(chain, timestep=float("nan"))
    with pytest.raises(TypeError, match="timestep"):
        to_mjcf(chain, timestep="0.01")
    with pytest.raises(ValueError, match="integrator must be one of"):
        to_mjcf(chain, integrator="euler")
    with pytest.raises(ValueError, match="name"):
        to_mjcf(chain, name='a"b')
    with pytest.raises(TypeError, match="Chain"):
        to_mjcf([Link("revolute", 1.0, 1.0)])
    with pytest.raises(TypeError, match="traced"):
        jax.jit(lambda c: len(to_mjcf(c)))(chain)


def test_zero_mass_and_inertia_become_tiny():
    """MuJoCo rejects zero mass/inertia on moving bodies; the export writes ``tiny`` instead."""
    chain = Chain([Link("revolute", 0.0, 1.0, inertia=0.5), Link("revolute", 1.0, 1.0, inertia=0.0, gear=1.0)])
    model, _ = mujoco_model(chain, 0.01)
    assert model.body_mass[1] == 1e-12 and model.body_inertia[2, 1] == 1e-12


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicit", "implicitfast"])
def test_every_integrator_loads(integrator):
    model, _ = mujoco_model(lg.systems.acrobot(), 0.01, integrator)
    assert model.opt.integrator == getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")


# --- dynamics ---------------------------------------------------------------------------------


@pytest.mark.parametrize("chain, dt", CHAINS)
def test_dynamics_match_mujoco(chain, dt):
    """M (mj_fullM), bias forces (qfrc_bias + damping) and qacc (mj_forward) to 1e-10."""
    model, data = mujoco_model(chain, dt)
    rng = np.random.default_rng(0)
    damping = np.zeros(chain.n) if chain.damping is None else np.asarray(chain.damping)
    q, qd = rng.uniform(-3, 3, (5, chain.n)), rng.uniform(-3, 3, (5, chain.n))
    u = rng.uniform(-2, 2, (5, chain.m))
    # vmapped and eager: evaluating is cheaper than compiling here
    M, bias, qdd = jax.vmap(
        lambda q, qd, u: (lg.mass_matrix(chain, q), lg.bias_forces(chain, q, qd), lg.forward_dynamics(chain, q, qd, u))
    )(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u))
    for k in range(5):
        data.qpos[:], data.qvel[:], data.ctrl[:] = q[k], qd[k], u[k]
        mujoco.mj_forward(model, data)
        M_mj = np.zeros((chain.n, chain.n))
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
    q_mj, qd_mj = mujoco_rollout(model, data, q0, qd0, us)
    q, qd = simulate(chain, q0, qd0, us, dt, lg.SemiImplicitEuler())
    assert rel(q, q_mj[0]) <= TRAJECTORY
    assert rel(qd, qd_mj[0]) <= TRAJECTORY
    if chain.damping is not None:
        # the test sees the implicit damping: with MuJoCo's eulerdamp off the trajectories part
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_EULERDAMP
        q_explicit, _ = mujoco_rollout(model, data, q0, qd0, us)
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
    q_mj, qd_mj = mujoco_rollout(model, data, q0, qd0, us)
    q, qd = simulate(chain, q0, qd0, us, dt, lg.RK4())
    assert rel(q, q_mj[0]) <= TRAJECTORY
    assert rel(qd, qd_mj[0]) <= TRAJECTORY
    # the tolerance tells integrators apart: MuJoCo's own Euler lands far from its RK4
    model_euler, data_euler = mujoco_model(chain, dt, "Euler")
    q_euler, _ = mujoco_rollout(model_euler, data_euler, q0, qd0, us)
    assert rel(q_euler[0], q_mj[0]) > 1e3 * TRAJECTORY
