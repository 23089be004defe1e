"""Ground contact and joint limits by penalty forces (``lagrange.PenaltyContact``, ``lagrange.PenaltyLimits``).

- Against an independent computation: MuJoCo's own kinematics and Jacobians (``mj_jac`` at each contact spot), the
  penalty forces computed here from them, ``qdd = M^-1 (B u - bias + tau_limits + sum J_s^T f)`` with MuJoCo's
  ``M``, ``qfrc_bias - qfrc_passive`` and its constraints disabled, at random states where some points penetrate
  and some joints are out of range, to 1e-10 relative (float64), on Gymnasium's hopper, half_cheetah and walker2d.
- The unrolled derivation (below ``RECURSIVE_MIN`` links) against the recursive one on the same chain.
- Finite derivatives at the law's kinks: a spot exactly on the ground (``d = 0``), zero sliding and approach
  velocity, a joint exactly on its bound; float32 and float64, forward and reverse mode. And through 40 steps of a
  hopper standing on the ground with zero sliding velocity.
- Energy: without damping the total energy including ``1/2 ke d^2`` and the limit springs is conserved to the
  integrator's order (semi-implicit Euler's first); with damping and friction it never increases (RK4, unactuated).
- Structure: a chain without contact has no contact code; the contact code grows with the points, not the links.
- The refusals, by name.
"""

from __future__ import annotations

import importlib.util
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import lagrange as lg
from lagrange.planar import recursive, unrolled
from lagrange.chain import Chain, Link
from lagrange.model.contact import PenaltyContact
from lagrange.planar.lower import lower as planar
from lagrange.interop.mjcf import from_mjcf
from lagrange.model.limits import PenaltyLimits
from tests.helpers import mujoco_forward, rel

GYM = pathlib.Path(importlib.util.find_spec("gymnasium").submodule_search_locations[0]) / "envs/mujoco/assets"
KE, KD, KF, MU = 2e4, 1e3, 1e3, 0.9
LIMIT_KE, LIMIT_KD = 1e3, 10.0


def _law():
    return PenaltyContact(KE, KD, KF, MU), PenaltyLimits(LIMIT_KE, LIMIT_KD)


def _independent(model, q, qd, u):
    """qdd from MuJoCo's M, bias, kinematics and Jacobians, with the penalty forces computed here."""
    data, M = mujoco_forward(model, q, qd, u)
    tau = data.qfrc_actuator - (data.qfrc_bias - data.qfrc_passive)
    out_of_range = 0
    for j in np.flatnonzero(model.jnt_limited):
        lo, hi = model.jnt_range[j]
        a, v = model.jnt_qposadr[j], model.jnt_dofadr[j]
        bound = lo if q[a] < lo else hi if q[a] > hi else None
        if bound is not None:
            tau[v] += LIMIT_KE * (bound - q[a]) - LIMIT_KD * qd[v]
            out_of_range += 1
    floor = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE)
    ground = data.geom_xpos[floor][2]
    touching = 0
    for g in range(model.ngeom):
        if g == floor or not (model.geom_contype[g] & model.geom_conaffinity[floor]
                              or model.geom_contype[floor] & model.geom_conaffinity[g]):
            continue
        centre, axis = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g, 1]
        for p in (centre - axis, centre + axis):  # every geom of these models is a capsule
            spot = p - np.array([0.0, 0.0, model.geom_size[g, 0]])
            depth = ground - spot[2]
            if depth <= 0:
                continue
            touching += 1
            jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
            mujoco.mj_jac(model, data, jacp, jacr, spot, model.geom_bodyid[g])
            v = jacp @ qd
            fn = KE * depth + KD * depth * max(-v[2], 0.0)
            ft = -np.clip(KF * v[0], -MU * KE * depth, MU * KE * depth)
            tau += jacp.T @ np.array([ft, 0.0, fn])
    return np.linalg.solve(M, tau), touching, out_of_range


@pytest.mark.parametrize("name", ["hopper", "half_cheetah", "walker2d"])
def test_forward_dynamics_equal_an_independent_computation(name):
    path = GYM / f"{name}.xml"
    contact, limits = _law()
    chain = from_mjcf(path, contact=contact, limits=limits)
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    rng = np.random.default_rng(7)
    k = 12
    q = rng.uniform(-1.3, 1.3, (k, model.nq))
    q[:, 1] = rng.uniform(-1.4, 0.1, k)  # the root's height: from well into the ground to just above it
    qd = rng.uniform(-3, 3, (k, model.nv))
    u = rng.uniform(-1, 1, (k, model.nu))
    ours = jax.jit(jax.vmap(lambda *x: lg.forward_dynamics(chain, *x)))(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(u))
    seen = np.zeros(2, int)
    for i in range(k):
        ref, touching, out = _independent(model, q[i], qd[i], u[i])
        seen += (touching, out)
        assert rel(ours[i], ref) <= 1e-10, (i, rel(ours[i], ref))
    assert seen[0] >= 20 and seen[1] >= 10, seen  # many points below the ground, many joints out of range


def test_the_unrolled_and_recursive_derivations_agree_with_contact():
    """A free capsule (x, z, pitch; the unrolled path) with two contact points, limits on z and the pitch."""
    chain = Chain([Link("prismatic", 0.0), Link("prismatic", 0.0, axis=np.pi / 2, range=(-0.5, 0.5)),
                   Link("revolute", 3.0, 0.6, inertia=0.2, offset=0.3, sense=-1, range=(-0.3, 0.4), gear=5.0,
                        contacts=[(0.05, 0.1, 0.05), (0.0, -0.6, 0.04)])],
                  contact=PenaltyContact(KE, KD, KF, MU, ground=-0.4), limits=PenaltyLimits(LIMIT_KE, LIMIT_KD))
    folded = planar(chain)  # the lowered chain, its parameters NumPy arrays (folded)
    rng = np.random.default_rng(1)
    q, qd, u = (jnp.asarray(rng.uniform(-s, s, (20, k))) for s, k in ((0.8, 3), (3.0, 3), (1.0, 1)))
    names = ("forward_dynamics", "bias_forces", "energy")

    @jax.jit
    def both(q, qd, u):  # every function of both derivations at the 20 states, one compilation
        return {f: [jax.vmap(lambda *x: getattr(m, f)(folded, *x))(*((q, qd, u) if f == "forward_dynamics" else
                                                                    (q, qd))) for m in (unrolled, recursive)]
                for f in names}

    out = both(q, qd, u)
    for f in names:
        a, b = out[f]
        assert rel(sum(a) if f == "energy" else a, sum(b) if f == "energy" else b) <= 1e-13, f


def _kinks(dtype):
    """A slide along z carrying a hinge whose link has a contact point: at q = (0.5, 0) the point's spot is exactly on
    the ground (radius 0.5), it neither slides nor approaches, and the slide sits exactly on its lower bound."""
    chain = Chain([Link("prismatic", 1.0, axis=np.pi / 2, range=(0.5, 2.0), contacts=[(0.0, 0.0, 0.5)]),
                   Link("revolute", 1.0, 1.0, contacts=[(0.0, -1.0, 0.1)], gear=1.0)],
                  contact=PenaltyContact(KE, KD, KF, MU), limits=PenaltyLimits(LIMIT_KE, LIMIT_KD))
    chain = jax.tree_util.tree_map(lambda x: x.astype(dtype) if eqx.is_array(x) else x, chain)
    return chain, jnp.asarray([0.5, np.pi], dtype), jnp.zeros(2, dtype)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_derivatives_are_finite_at_the_kinks(dtype):
    chain, q, qd = _kinks(dtype)
    u = jnp.zeros(1, dtype)

    def f(params, q, qd):
        c = eqx.tree_at(lambda c: (c.contact.ke, c.contact.kd, c.contact.kf, c.contact.mu, c.limits.ke), chain, params)
        return lg.forward_dynamics(c, q, qd, u)

    params = (chain.contact.ke, chain.contact.kd, chain.contact.kf, chain.contact.mu, chain.limits.ke)
    # both modes in one compiled program (op by op they cost a compilation per operation)
    rev, fwd = jax.jit(lambda *x: (jax.jacrev(f, argnums=(0, 1, 2))(*x), jax.jacfwd(f, argnums=(0, 1, 2))(*x)))(
        params, q, qd)
    for leaf in jax.tree_util.tree_leaves((rev, fwd)):
        assert jnp.all(jnp.isfinite(leaf)) and leaf.dtype == dtype


def test_gradients_through_a_hopper_standing_on_the_ground_are_finite():
    """40 steps of semi-implicit Euler (1 ms) from the hopper standing with its foot on the ground, not sliding: the
    gradient of the final state with respect to the initial state, the controls and the contact parameters."""
    contact, limits = _law()
    chain = from_mjcf(GYM / "hopper.xml", contact=contact, limits=limits)
    q0 = jnp.zeros(chain.nv).at[1].set(-0.0004)  # the foot's spots 0.4 mm deep
    us = jnp.zeros((40, chain.m))

    @eqx.filter_jit
    @eqx.filter_grad
    def grad(args):
        c, q0, us = args
        traj = lg.simulate(c, q0, jnp.zeros(chain.nv), us, 0.001, lg.SemiImplicitEuler())
        return jnp.sum(traj.q[-1]) + jnp.sum(traj.qd[-1])

    g = grad((chain, q0, us))
    leaves = jax.tree_util.tree_leaves(g)
    assert leaves and all(bool(jnp.all(jnp.isfinite(x))) for x in leaves)
    assert float(jnp.abs(g[0].contact.ke)) > 0  # the contact is felt


def _drop(damped: bool):
    """The biped of test_trees without actuation, dropped from 0.1 m onto the ground, feet and knees touching."""
    links = [Link("prismatic", 0.0), Link("prismatic", 0.0, axis=np.pi / 2),
             Link("revolute", 8.0, 0.5, inertia=0.4, offset=np.pi, contacts=[(0.0, 0.0, 0.05)]),
             Link("revolute", 2.0, 0.4, parent=2, attach=(0.0, 0.0), offset=np.pi, range=(-1.0, 1.0)),
             Link("revolute", 1.0, 0.4, contacts=[(0.0, -0.4, 0.03)], range=(-1.5, 0.1)),
             Link("revolute", 2.0, 0.4, parent=2, attach=(-0.1, 0.0), offset=np.pi),
             Link("revolute", 1.0, 0.4, contacts=[(0.0, -0.4, 0.03)])]
    contact = PenaltyContact(1e4, 100.0 if damped else 0.0, 500.0 if damped else 0.0, 0.8, ground=-0.93)
    return Chain(links, contact=contact, limits=PenaltyLimits(500.0, 5.0 if damped else 0.0))


def test_energy_without_damping_is_conserved_at_the_integrators_order():
    """Without damping or friction the energy, penalty springs included, is conserved to semi-implicit Euler's first
    order through landings (measured: the error halves with the step, order 0.98-1.00 from 0.4 to 0.025 ms). RK4's
    error also falls but at no steady order (1.3, 3.3, 2.3, 0.8 over the same steps): the law's derivative jumps at
    each touchdown and lift-off, so the steps that cross one lose RK4's smoothness.

    Both steps run in one compiled program (the step an argument, the step count that of the finer one); the coarser
    step's error is read over its own 0.3 s, the states of a run of ``int(0.3 / dt)`` steps."""
    chain = _drop(damped=False)
    q0 = jnp.asarray([0.0, 0.1, 0.1, 0.3, -0.2, -0.2, 0.1])
    qd0 = jnp.asarray([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    steps = {dt: int(0.3 / dt) for dt in (2e-4, 1e-4)}

    @jax.jit
    def run(dt):
        traj = lg.simulate(chain, q0, qd0, None, dt, lg.SemiImplicitEuler(), steps=max(steps.values()))
        return traj.q[:, 1], sum(lg.energy(chain, traj.q, traj.qd)), sum(lg.energy(chain, q0, qd0))

    errs = []
    for dt, n in steps.items():
        z, e, e0 = (np.asarray(x) for x in run(jnp.asarray(dt)))
        z, e = z[: n + 1], e[: n + 1]  # the states of the n-step run
        assert float(np.min(z)) < -0.02  # it landed
        errs.append(float(np.max(np.abs(e - e0))))
    assert 0.9 < np.log2(errs[0] / errs[1]) < 1.1, errs


def test_energy_with_damping_never_increases():
    chain = _drop(damped=True)
    q0 = jnp.asarray([0.0, 0.1, 0.1, 0.3, -0.2, -0.2, 0.1])
    @jax.jit
    def run():
        traj = lg.simulate(chain, q0, jnp.zeros(7), None, 1e-4, lg.RK4(), steps=3000)
        return traj.q[:, 1], sum(lg.energy(chain, traj.q, traj.qd))  # the energy in the same compiled program

    z, e = (np.asarray(x) for x in run())
    assert float(np.min(z)) < -0.02
    assert np.all(np.diff(e) <= 1e-9 * np.abs(e[0])), float(np.max(np.diff(e)))


def _ops(chain):
    jaxpr = jax.make_jaxpr(lambda q, qd: lg.forward_dynamics(chain, q, qd, check=False))(jnp.zeros(chain.nv),
                                                                                        jnp.zeros(chain.nv))
    return len(jaxpr.eqns) + sum(len(e.params.get("jaxpr", jaxpr).eqns) if hasattr(e.params.get("jaxpr"), "eqns")
                                 else 0 for e in jaxpr.eqns)


def test_contact_costs_nothing_where_nothing_can_touch():
    """The contact code runs only for the contact points: a chain without contact and the same chain with a point
    differ by the points' ops, which do not grow with the links (one point on 4 and on 8 links)."""
    def chain(n, point):
        links = [Link("revolute", 1.0, 1.0, contacts=[(0.0, -1.0, 0.1)] if point and i == n - 1 else ())
                 for i in range(n)]
        return Chain(links, contact=PenaltyContact(KE, KD, KF, MU) if point else None)

    extra = [_ops(chain(n, True)) - _ops(chain(n, False)) for n in (4, 8)]
    assert extra[0] > 0 and extra[0] == extra[1], extra
    assert chain(4, False).contact is None and planar(chain(4, False)).contact_points is None


@pytest.mark.parametrize("make, error, message", [
    (lambda: PenaltyContact(-1.0, 0, 0, 0), ValueError, r"PenaltyContact\.ke must be finite and > 0"),
    (lambda: PenaltyContact(1.0, -1.0, 0, 0), ValueError, r"PenaltyContact\.kd must be finite and >= 0"),
    (lambda: PenaltyContact(1.0, 0, 0, "a"), TypeError, r"PenaltyContact\.mu must be a real number"),
    (lambda: PenaltyContact(1.0, 0, 0, 0, ground=float("nan")), ValueError,
     r"PenaltyContact\.ground must be a finite scalar height in m"),
    (lambda: PenaltyLimits(0.0), ValueError, r"PenaltyLimits\.ke must be finite and > 0"),
    (lambda: Link("revolute", 1.0, range=(1.0, -1.0)), ValueError, r"Link\.range must be finite with lower < upper"),
    (lambda: Link("revolute", 1.0, contacts=[(0.0, 1.0)]), ValueError, r"Link\.contacts\[0\] must be a point \(x, z, "
                                                                        r"radius\) of three numbers"),
    (lambda: Link("revolute", 1.0, contacts=[(0.0, 1.0, -0.1)]), ValueError, r"radius >= 0"),
    (lambda: Chain([Link("revolute", 1.0, 1.0, contacts=[(0, 0, 0.1)])]), ValueError,
     r"links \[0\] have contact points but the chain has no contact law: pass Chain\(\.\.\., contact="),
    (lambda: Chain([Link("revolute", 1.0, 1.0)], contact=PenaltyContact(1, 0, 0, 0)), ValueError,
     r"Chain\.contact is given but no link has contact points"),
    (lambda: Chain([Link("revolute", 1.0, 1.0, range=(-1, 1))]), ValueError,
     r"links \[0\] have a range but the chain has no limit law"),
    (lambda: Chain([Link("revolute", 1.0, 1.0)], limits=PenaltyLimits(1.0)), ValueError,
     r"Chain\.limits is given but no link has a range"),
    (lambda: Chain([Link("revolute", 1.0, 1.0, contacts=[(0, 0, 0.1)])], contact=3.0), TypeError,
     r"Chain\.contact must be a lagrange\.PenaltyContact"),
])
def test_bad_contact_and_limits_are_refused_by_name(make, error, message):
    with pytest.raises(error, match=message):
        make()


def test_from_mjcf_reads_a_box_that_can_touch_the_ground_as_its_corners_on_the_planar_backend():
    """A planar box's eight corners project onto the plane in pairs; the planar backend presses each of them as the
    general algorithms press the corners in 3-D, so the two agree while four corners are below the ground."""
    xml = """<mujoco><worldbody><geom name="floor" type="plane" size="5 5 1"/>
      <body name="b" pos="0 0 1"><joint name="z" type="slide" axis="0 0 1"/><joint name="r" type="hinge" axis="0 1 0"/>
      <geom name="box" type="box" size="0.1 0.1 0.1"/><geom name="ball" type="ellipsoid" size="0.1 0.1 0.1"
      contype="0" conaffinity="0"/></body></worldbody></mujoco>"""
    tree = from_mjcf(xml, contact=PenaltyContact(KE, KD, KF, MU))
    assert len(tree.bodies[0].contacts) == 8 and planar(tree) is not None
    q, qd = jnp.asarray([-0.95, 0.2]), jnp.asarray([-0.3, 0.5])  # the box's centre 0.05 above the floor, turned
    fast = lg.forward_dynamics(tree, q, qd)
    general = lg.dynamics.prepare(tree, general=True).forward_dynamics(q, qd)
    assert rel(fast, general) <= 1e-12 and float(jnp.abs(fast[0])) > 1.0  # the ground pushes
    with pytest.raises(NotImplementedError, match="geom 'ball' is a ellipsoid that can touch the ground"):
        from_mjcf(xml.replace('contype="0" conaffinity="0"', ""), contact=PenaltyContact(KE, KD, KF, MU))
    with pytest.raises(ValueError, match="limits must be one of .* or a lagrange.PenaltyLimits"):
        from_mjcf(xml, limits=3)
