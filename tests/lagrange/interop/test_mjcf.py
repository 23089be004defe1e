"""The MJCF export (lagrange/interop/mjcf.py): the XML it writes (compiler, options, joints, geoms, motors), the
parameters MuJoCo compiles from it (masses, inertias, centres of mass, damping, armature, gears, timestep, gravity)
and the sign convention of its hinge axis, its argument checks, and that every MuJoCo integrator loads it. The
dynamics of the exported model against ours are in ``tests/lagrange/test_against_mujoco.py``."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import jax
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.interop.mjcf import to_mjcf
from lagrange.planar.lower import lower as planar
from tests.helpers import CHAINS, mujoco_model, seeded_chain


def test_export_structure():
    chain = seeded_chain(3)
    root = ET.fromstring(to_mjcf(chain, timestep=0.002, integrator="RK4", name="demo"))
    assert root.get("model") == "demo"
    assert root.find("compiler").get("inertiafromgeom") == "false"
    opt = root.find("option")
    assert (opt.get("timestep"), opt.get("integrator")) == ("0.002", "RK4")
    assert root.find("custom/numeric").attrib == {"name": "matrix_inv_iterations", "data": "0"}
    joints = root.findall(".//joint")
    assert [j.get("type") for j in joints] == ["hinge" if k == "revolute" else "slide" for k in planar(chain).joints]
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
    lowered = planar(chain)
    np.testing.assert_array_equal(model.body_mass[1:], np.asarray(chain.mass))
    np.testing.assert_array_equal(model.body_inertia[1:, 1], np.where(lowered.inertia > 0, lowered.inertia, 1e-12))
    np.testing.assert_array_equal(model.body_ipos[1:, 2], -np.asarray(lowered.com))
    damping = np.zeros(chain.nv) if lowered.damping is None else np.asarray(lowered.damping)
    armature = np.zeros(chain.nv) if lowered.armature is None else np.asarray(lowered.armature)
    np.testing.assert_array_equal(model.dof_damping, damping)
    np.testing.assert_array_equal(model.dof_armature, armature)
    np.testing.assert_array_equal(model.actuator_gear[:, 0], np.asarray(chain.gear))
    np.testing.assert_array_equal(model.actuator_trnid[:, 0], chain.actuated)
    assert model.opt.timestep == dt and model.opt.gravity[2] == -float(lowered.gravity)


def test_positive_hinge_angle_swings_towards_plus_x():
    chain = lg.systems.pendulum()
    model, data = mujoco_model(chain, 0.01)
    data.qpos[:] = 0.3
    mujoco.mj_kinematics(model, data)
    # the centre of mass at l/2 along d(0.3) = (sin 0.3, -cos 0.3)
    np.testing.assert_allclose(data.xipos[1, [0, 2]], 0.5 * np.array([math.sin(0.3), -math.cos(0.3)]), rtol=0,
                               atol=1e-15)


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
