"""Ground contact and joint limits on 3-D trees, against an independent computation on MuJoCo's kinematics.

The oracle: MuJoCo with every constraint disabled gives ``M`` and ``qfrc_bias - qfrc_passive``; the contact spots are
taken from MuJoCo's own geom poses (a capsule's end points, a sphere's centre, a box's corners, lowered by the radius),
their Jacobians from ``mj_jac``, and DFlex's law and the limits' law are written out here in NumPy, so that
``qacc = M^-1 (ctrl forces - bias + sum J^T f + tau_limits)``. Float64.
"""

from __future__ import annotations

import pathlib
import re

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.interop.mjcf import from_mjcf
from lagrange.model.joints import Free, Hinge
from lagrange.model.tree import Body, Tree
from tests.helpers import mujoco_terms, rel

GYM = pathlib.Path(__import__("gymnasium").__file__).parent / "envs" / "mujoco" / "assets"
KE, KD, KF, MU = 2.0e4, 1.0e3, 1.0e3, 0.9
LKE, LKD = 1.0e3, 10.0


def _free_flight(path):
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return model


def _spots(model, data):
    """Every geom that can touch the world's plane: ``(body, spot (3,), radius)`` per contact point, from MuJoCo."""
    plane = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE)
    out = []
    for g in range(model.ngeom):
        if g == plane or model.geom_bodyid[g] == 0:
            continue
        if not (model.geom_contype[g] & model.geom_conaffinity[plane] or model.geom_contype[plane]
                & model.geom_conaffinity[g]):
            continue
        c, R, size = np.array(data.geom_xpos[g]), np.array(data.geom_xmat[g]).reshape(3, 3), model.geom_size[g]
        kind = model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            pts = [(c - R[:, 2] * size[1], size[0]), (c + R[:, 2] * size[1], size[0])]
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            pts = [(c, size[0])]
        else:
            raise AssertionError(f"geom type {kind} not in these models")
        out += [(int(model.geom_bodyid[g]), p - np.array([0, 0, r]), r) for p, r in pts]
    return out, float(model.geom_pos[plane][2])


def oracle_qacc(model, q, qd, u):
    """``qacc`` by the law written out on MuJoCo's kinematics (constraints disabled in ``model``)."""
    M, bias, _ = mujoco_terms(model, q, qd, u)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.ctrl[:] = q, qd, u
    mujoco.mj_forward(model, data)
    tau = np.array(data.qfrc_actuator) - bias
    spots, ground = _spots(model, data)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for body, s, _ in spots:
        mujoco.mj_jac(model, data, jacp, jacr, s, body)
        v = jacp @ qd
        d = ground - s[2]
        if d <= 0:
            continue
        fn = KE * d + KD * d * max(-v[2], 0.0)
        vt = v[:2]
        speed = np.linalg.norm(vt)
        ft = -vt * KF if KF * speed <= MU * KE * d else -(vt / speed) * MU * KE * d
        tau = tau + jacp.T @ np.array([ft[0], ft[1], fn])
    hinge_or_slide = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))  # (an enum != its int)
    for j in range(model.njnt):
        if model.jnt_limited[j] and model.jnt_type[j] in hinge_or_slide:
            a, b = model.jnt_qposadr[j], model.jnt_dofadr[j]
            lo, hi = model.jnt_range[j]
            if q[a] < lo:
                tau[b] += LKE * (lo - q[a]) - LKD * qd[b]
            elif q[a] > hi:
                tau[b] += LKE * (hi - q[a]) - LKD * qd[b]
    return np.linalg.solve(M, tau), len([1 for _, s, _ in spots if ground - s[2] > 0])


def _state(model, seed):
    """A state with the root tilted and lowered into the ground, the joints moved past their ranges."""
    rng = np.random.default_rng(seed)
    q = np.array(model.qpos0, float)
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    angle = 0.4
    q[3:7] = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    for j in range(1, model.njnt):
        a = model.jnt_qposadr[j]
        lo, hi = model.jnt_range[j]
        q[a] = rng.choice([lo - 0.2, hi + 0.2, 0.5 * (lo + hi)]) if model.jnt_limited[j] else rng.uniform(-0.5, 0.5)
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    spots, ground = _spots(model, data)
    lows = sorted(s[2] for _, s, _ in spots)
    q[2] += ground - lows[min(3, len(lows) - 1)] - 1e-3  # the four lowest spots below the ground
    return q, rng.uniform(-1.0, 1.0, model.nv), rng.uniform(-1.0, 1.0, model.nu)


@pytest.mark.parametrize("name", ["ant", "humanoid"])
def test_qdd_equals_the_oracle_with_points_in_contact_and_joints_out_of_range(name):
    path = GYM / f"{name}.xml"
    model = _free_flight(path)
    tree = from_mjcf(path, contact=lg.PenaltyContact(KE, KD, KF, MU), limits=lg.PenaltyLimits(LKE, LKD))
    assert isinstance(tree, Tree) and tree.contact is not None and tree.limits is not None
    fd = jax.jit(lambda q, qd, u: lg.forward_dynamics(tree, q, qd, u))
    for seed in range(3):
        q, qd, u = _state(model, seed)
        want, touching = oracle_qacc(model, q, qd, u)
        assert touching >= 4
        out = np.asarray(fd(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u)))
        assert rel(out, want) < 1e-10, (seed, rel(out, want))


def _ball(z, vx=0.0):
    """A free sphere of radius 0.1 at height ``z``, moving along x at ``vx``."""
    tree = Tree([Body(1.0, (0.004, 0.004, 0.004), joints=[Free()], contacts=[(0.0, 0.0, 0.0, 0.1)])],
                contact=lg.PenaltyContact(KE, KD, KF, MU))
    q = jnp.array([0.0, 0.0, z, 1.0, 0.0, 0.0, 0.0])
    qd = jnp.array([vx, 0.0, 0.0, 0.0, 0.0, 0.0])
    return tree, q, qd


def test_gradients_are_finite_at_touch_and_without_sliding_and_match_central_differences():
    tree, q, qd = _ball(0.1)  # exactly touching, no sliding velocity: d = 0, vt = 0

    @jax.jit
    def value(q, qd):
        tr = lg.simulate(tree, q, qd, jnp.zeros((40, 0)), 1e-3, lg.SemiImplicitEuler(), check=False)
        return jnp.sum(tr.q[-1, :3] ** 2) + jnp.sum(tr.qd[-1] ** 2)

    def loss(q, qd):
        return value(q, qd)

    grad = jax.jit(jax.grad(value, argnums=(0, 1)))
    g = grad(q, qd)
    assert all(bool(jnp.all(jnp.isfinite(x))) for x in g)
    # away from the kinks: pressed in, approaching and sliding, so the friction saturates (the normalised tangent)
    q = q.at[2].set(0.095)  # the same tree: the jitted functions are reused
    qd = qd.at[0].set(0.5).at[1].set(0.3).at[2].set(-0.2)
    gq, gqd = grad(q, qd)
    eps = 1e-6
    for k in (0, 2):
        e = jnp.zeros(7).at[k].set(eps)
        fdq = (loss(q + e, qd) - loss(q - e, qd)) / (2 * eps)
        assert abs(float(gq[k]) - float(fdq)) < 1e-6 * max(1.0, abs(float(fdq))), (k, gq[k], fdq)
    for k in (0, 1, 2):
        e = jnp.zeros(6).at[k].set(eps)
        fdv = (loss(q, qd + e) - loss(q, qd - e)) / (2 * eps)
        assert abs(float(gqd[k]) - float(fdv)) < 1e-6 * max(1.0, abs(float(fdv))), (k, gqd[k], fdv)


def test_a_resting_ball_feels_its_weight_and_the_law_at_zero_sliding():
    """At depth d, at rest: the normal force is ke d and there is no friction (so q̈_z = ke d / m - g)."""
    tree, q, qd = _ball(0.099)
    qdd = jax.jit(lg.forward_dynamics)(tree, q, qd)
    assert abs(float(qdd[2]) - (KE * 0.001 - 9.81)) < 1e-9
    assert float(jnp.max(jnp.abs(qdd[jnp.array([0, 1, 3, 4, 5])]))) < 1e-12
    fn, ft = tree.contact.forces_3d(jnp.array(0.0), jnp.array(0.0), jnp.zeros(2))
    assert float(fn) == 0.0 and float(jnp.max(jnp.abs(ft))) == 0.0


def test_bad_contact_and_limit_input_is_refused_by_name():
    with pytest.raises(ValueError, match="contacts"):
        Body(1.0, contacts=[(0.0, 0.0, 0.0, -0.1)], joints=[Free()])
    with pytest.raises(ValueError, match="contact law"):
        Tree([Body(1.0, (1, 1, 1), joints=[Free()], contacts=[(0.0, 0.0, 0.0, 0.1)])])
    with pytest.raises(ValueError, match="range"):
        Hinge(range=(1.0, -1.0))
    with pytest.raises(ValueError, match="limit law"):
        Tree([Body(1.0, (1, 1, 1), joints=[Hinge(range=(-1.0, 1.0))])])
    xml = """<mujoco><worldbody><geom type="plane" size="5 5 .1"/><body pos="0 0 1"><freejoint/>
      <geom type="sphere" size=".1"/><body pos="0 0 -.3"><joint type="ball" range="0 30"/>
      <geom type="capsule" fromto="0 0 0 0 0 -.3" size=".05"/></body></body></worldbody></mujoco>"""
    with pytest.raises(NotImplementedError, match="ball"):
        from_mjcf(xml, contact=lg.PenaltyContact(KE, KD, KF, MU), limits=lg.PenaltyLimits(LKE))
    cyl = xml.replace('type="sphere" size=".1"', 'type="cylinder" size=".1 .1"').replace(' range="0 30"', "")
    with pytest.raises(NotImplementedError, match="cylinder"):
        from_mjcf(cyl, contact=lg.PenaltyContact(KE, KD, KF, MU))


def test_a_dropped_humanoids_energy_error_is_first_order_through_the_landing():
    """Gymnasium's humanoid dropped 0.3 m, tilted, onto the ground with the conservative law (kd = kf = 0) and no
    joint damping: the total energy (penalty springs included) is conserved by the flow, and semi-implicit Euler's
    largest error over 0.6 s, through the landing, halves when the step does (first order)."""
    xml = re.sub(r'damping="[^"]*"', 'damping="0"', (GYM / "humanoid.xml").read_text())
    tree = from_mjcf(xml, contact=lg.PenaltyContact(KE, 0.0, 0.0, MU), limits="ignore")
    assert all(float(j.damping) == 0.0 for j in tree.joints)
    q0 = np.array(tree.neutral(), float)
    q0[2] += 0.3
    q0[3:7] = [np.cos(0.15), np.sin(0.15), 0.0, 0.0]
    q0 = jnp.asarray(q0)

    @jax.jit
    def worst(h):
        qd0 = jnp.zeros(tree.nv)
        e0 = sum(lg.energy(tree, q0, qd0))

        def body(_, carry):
            q, qd, err = carry
            q, qd = lg.step(tree, q, qd, jnp.zeros(tree.m), h, lg.SemiImplicitEuler())
            return q, qd, jnp.maximum(err, jnp.abs(sum(lg.energy(tree, q, qd)) - e0))

        n = jnp.round(0.6 / h).astype(int)
        q, _, err = jax.lax.fori_loop(0, n, body, (q0, qd0, jnp.zeros(())))
        return err, q[2]

    errors, heights = zip(*(worst(jnp.asarray(h)) for h in (1e-3, 5e-4, 2.5e-4)))
    assert max(float(z) for z in heights) < float(q0[2]) - 0.25  # it fell and landed
    ratios = [float(errors[0] / errors[1]), float(errors[1] / errors[2])]
    assert all(1.6 < r < 2.5 for r in ratios), (errors, ratios)
