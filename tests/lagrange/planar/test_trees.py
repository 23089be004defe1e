"""Planar kinematic trees: branches, forests, attach points, joint springs and hinges of either sense.

Against the literal Euler-Lagrange derivation (``oracles/euler_lagrange.py``, which writes each link's position along
its path from the world) on both derivations (unrolled below ``RECURSIVE_MIN`` links, recursive from it); against
Pinocchio's CRBA, RNEA and ABA on a branched tree built independently from the same parameters
(``oracles/pinocchio.py``); gradients through a tree rollout against central differences; the energy of an undamped
tree with springs conserved at RK4's order; and the clear errors of a tree defined by hand. Tolerances as in
``test_dynamics.py`` (1e-12 relative for M, bias and qdd in float64).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from oracles import euler_lagrange as el
from oracles.pinocchio import pinocchio_model
from lagrange.chain import WORLD, Chain, Link
from lagrange.planar.lower import lower as planar
from tests.helpers import assert_close


def biped(**kw) -> Chain:
    """A planar biped defined by hand: a floating base (x, z, pitch) whose torso carries two legs of thigh and shin,
    the second leg attached 0.1 m behind the first, one knee turning the other way, springs on the knees."""
    return Chain([
        Link("prismatic", 0.0),                                              # x
        Link("prismatic", 0.0, axis=np.pi / 2),                              # z
        Link("revolute", 8.0, 0.5, inertia=0.4, offset=np.pi, armature=0.1),   # torso, upright, pitch
        Link("revolute", 2.0, 0.4, parent=2, attach=(0.0, 0.0), offset=np.pi, damping=0.5, gear=50.0),   # front hip
        Link("revolute", 1.0, 0.4, stiffness=30.0, springref=0.2, gear=30.0),                   # front shin, knee
        Link("revolute", 2.0, 0.4, parent=2, attach=(-0.1, 0.0), offset=np.pi, damping=0.5, gear=50.0),  # back hip
        Link("revolute", 1.0, 0.4, stiffness=30.0, sense=-1, gear=30.0),                       # back shin
    ], **kw)


def test_a_tree_by_hand():
    chain = biped()
    assert chain.parents == (-1, 0, 1, 2, 3, 2, 5) and not planar(chain).serial
    links = planar(chain)
    assert links.children(2) == (3, 5) and links.path(6) == (0, 1, 2, 5, 6) and links.attached == (3, 5)
    assert links.sprung == (4, 6) and links.senses[6] == -1
    again = Chain(chain.links())  # the links round-trip
    assert again.parents == chain.parents and planar(again).attached == links.attached
    assert planar(again).senses == links.senses
    q = jnp.zeros(7)
    tips = lg.kinematics.tip_positions(chain, q)[:, ::2]  # (x, z): the chain lives in the world's x-z plane
    joints = lg.positions(chain, q)[:, ::2]
    # at q = 0 the torso points up from the base; the front leg hangs from the base, the back one from 0.1 m behind
    # it (x = -0.1 in the upright torso's frame, whose x is the world's -x); each foot 0.8 m below its hip
    np.testing.assert_allclose(np.asarray(tips[2]), [0.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(np.asarray(joints[3]), [0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.asarray(joints[5]), [0.1, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.asarray(tips[4]), [0.0, -0.8], atol=1e-15)
    np.testing.assert_allclose(np.asarray(tips[6]), [0.1, -0.8], atol=1e-15)


def _oracle(chain, q, qd, u):
    M, bias = el.mass_matrix(chain, q), el.bias_forces(chain, q, qd)
    qdd = jnp.linalg.solve(M, lg.actuation_matrix(chain) @ u - bias)
    return M, bias, qdd, sum(el.energy(chain, q, qd))


def _ours(chain, q, qd, u):
    return (lg.mass_matrix(chain, q), lg.bias_forces(chain, q, qd), lg.forward_dynamics(chain, q, qd, u),
            sum(lg.energy(chain, q, qd)))


def small_tree() -> Chain:
    """Three links, the unrolled derivation: a cart carrying two pendulums side by side, one turning the other way."""
    return Chain([
        Link("prismatic", 1.0, gear=10.0, damping=0.2),
        Link("revolute", 0.5, 0.7, parent=0, attach=(0.2, 0.0), stiffness=2.0, springref=0.3),
        Link("revolute", 0.3, 0.5, parent=0, attach=(-0.2, 0.05), sense=-1, com_normal=0.05, offset=0.4),
    ])


def forest() -> Chain:
    """Two trees: a two-link arm and, beside it, a target on two slides (Gymnasium's reacher shape), no gravity."""
    return Chain([
        Link("revolute", 0.1, 0.1, armature=0.01, gear=1.0),
        Link("revolute", 0.1, 0.11, armature=0.01, gear=1.0),
        Link("prismatic", 0.05, parent=WORLD, attach=(0.1, -0.1), armature=0.001),
        Link("prismatic", 0.05, axis=np.pi / 2, armature=0.001),
    ], gravity=0.0)


@pytest.mark.parametrize("make", [small_tree, biped, forest])
def test_trees_match_the_literal_derivation(make):
    chain = make()
    rng = np.random.default_rng(chain.nv)
    k = 6
    q = jnp.asarray(rng.uniform(-np.pi, np.pi, (k, chain.nv)))
    qd = jnp.asarray(rng.uniform(-3, 3, (k, chain.nv)))
    u = jnp.asarray(rng.uniform(-1, 1, (k, chain.m)))
    @jax.jit
    def both(q, qd, u):  # ours, the oracle's, and inverse dynamics at our qdd: one compilation
        ours = jax.vmap(lambda *x: _ours(chain, *x))(q, qd, u)
        tau = jax.vmap(lambda q, qd, qdd: lg.inverse_dynamics(chain, q, qd, qdd))(q, qd, ours[2])
        return ours, jax.vmap(lambda *x: _oracle(chain, *x))(q, qd, u), tau

    ours, ref, tau = both(q, qd, u)
    cond = float(np.max(np.linalg.cond(np.asarray(ref[0]))))
    for name, a, b, tol in zip(("M", "bias", "qdd", "energy"), ours, ref, (1e-12, 1e-12, 1e-13 * max(cond, 10), 1e-12)):
        assert_close(a, b, rel=tol, what=name)
    # inverse dynamics undoes forward dynamics on the tree
    assert_close(tau, jnp.einsum("ij,kj->ki", lg.actuation_matrix(chain), u), rel=1e-11, what="inverse dynamics")


def test_a_branched_tree_matches_pinocchio():
    """The biped without springs and damping (Pinocchio has neither): M by CRBA, the bias by RNEA at zero
    acceleration, qdd by ABA with the joints' armature, at random states."""
    import pinocchio as pin  # a test dependency: CI installs it, a skip would hide a failure
    links = [lk.__class__(**{**{f: getattr(lk, f) for f in ("joint", "mass", "length", "com", "inertia", "axis",
                                                             "armature", "gear", "com_normal", "offset", "parent",
                                                             "attach", "sense")}}) for lk in biped().links()]
    chain = Chain(links)
    model = pinocchio_model(chain)
    data = model.createData()
    sign = np.array([-s if j == "revolute" else 1.0 for j, s in zip(planar(chain).joints, planar(chain).senses)])
    model.armature = np.zeros(chain.nv) if planar(chain).armature is None else np.asarray(planar(chain).armature)
    rng = np.random.default_rng(5)
    q, qd, tau = rng.uniform(-2, 2, (5, chain.nv)), rng.uniform(-3, 3, (5, chain.nv)), rng.uniform(-5, 5, (5, chain.nv))

    @jax.jit
    def ours(q, qd, tau):
        M, bias = lg.mass_matrix(chain, q), lg.bias_forces(chain, q, qd)
        return M, bias, jnp.linalg.solve(M, tau[..., None])[..., 0] - jnp.linalg.solve(M, bias[..., None])[..., 0]

    M, bias, qdd = ours(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(tau))
    for k in range(len(q)):
        Mp = pin.crba(model, data, sign * q[k])
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert_close(M[k], sign[:, None] * Mp * sign[None, :], what="M")
        assert_close(bias[k], sign * pin.rnea(model, data, sign * q[k], sign * qd[k], np.zeros(chain.nv)), what="bias")
        assert_close(qdd[k], sign * pin.aba(model, data, sign * q[k], sign * qd[k], sign * tau[k]), rel=1e-11,
                     what="qdd")


def test_gradients_through_a_tree_rollout_match_central_differences():
    """d(final state)/d(initial state, masses, stiffness) through 40 steps of semi-implicit Euler on the biped, against
    central differences (h = 1e-6). One compiled program gives the gradient and, at the shifted inputs, the values the
    differences take."""
    chain = biped()
    q0 = jnp.asarray(np.random.default_rng(2).uniform(-0.3, 0.3, chain.nv))
    qd0 = jnp.zeros(chain.nv)
    us = jnp.asarray(np.random.default_rng(3).uniform(-0.2, 0.2, (40, chain.m)))

    def objective(c, q0):
        traj = lg.simulate(c, q0, qd0, us, 0.005, lg.SemiImplicitEuler())
        return jnp.sum(traj.q[-1] ** 2) + jnp.sum(traj.qd[-1])

    value_and_grad = eqx.filter_jit(jax.value_and_grad(objective, argnums=(0, 1)))

    def final(c, q0):
        return value_and_grad(c, q0)[0]

    g_chain, g_q0 = value_and_grad(chain, q0)[1]
    h = 1e-6
    for i in (1, 2, 6):
        e = jnp.zeros(chain.nv).at[i].set(h)
        fd = (final(chain, q0 + e) - final(chain, q0 - e)) / (2 * h)
        assert abs(float(g_q0[i]) - float(fd)) <= 1e-6 * max(1.0, abs(float(fd)))
    # a link's mass, a knee's spring and the back hip's attach point (x): leaves of the tree's bodies and joints
    leaves = {"mass 2": (lambda c: c.bodies[2].mass, ()), "mass 6": (lambda c: c.bodies[6].mass, ()),
              "stiffness 4": (lambda c: c.bodies[4].joints[0].stiffness, ()),
              "attach 5": (lambda c: c.bodies[5].pos, 0)}
    for field, (leaf, idx) in leaves.items():
        def at(d):
            return final(eqx.tree_at(leaf, chain, jnp.asarray(leaf(chain)).at[idx].add(d)), q0)

        fd = (at(h) - at(-h)) / (2 * h)
        assert abs(float(leaf(g_chain)[idx]) - float(fd)) <= 1e-6 * max(1.0, abs(float(fd))), field


def test_energy_of_a_sprung_tree_is_conserved_at_rk4_order():
    """The biped without damping or actuation: the energy error of RK4 falls ~16x when the step halves (measured order
    between 2 and 1 ms: 4.0). Both steps run in one compiled program (the step an argument, the step count that of the
    finer one); the coarser step's error is read over its own 0.4 s."""
    links = [lk.__class__(**{f: getattr(lk, f) for f in ("joint", "mass", "length", "com", "inertia", "axis",
                                                         "armature", "com_normal", "offset", "parent", "attach",
                                                         "stiffness", "springref", "sense")}) for lk in biped().links()]
    chain = Chain(links)
    q0 = jnp.asarray([0.0, 0.0, 0.3, 0.5, -0.4, -0.2, 0.6])
    qd0 = jnp.asarray([0.5, 1.0, -0.5, 1.0, 0.0, -1.0, 2.0])
    steps = {dt: int(0.4 / dt) for dt in (0.002, 0.001)}

    @jax.jit
    def run(dt):
        traj = lg.simulate(chain, q0, qd0, None, dt, lg.RK4(), steps=max(steps.values()))
        return sum(lg.energy(chain, traj.q, traj.qd)), sum(lg.energy(chain, q0, qd0))

    errs = []
    for dt, n in steps.items():
        e, e0 = (np.asarray(x) for x in run(jnp.asarray(dt)))
        errs.append(float(np.max(np.abs(e[: n + 1] - e0))))  # the states of the n-step run
    order = np.log2(errs[0] / errs[1])
    assert 3.6 < order < 4.4, (errs, order)


@pytest.mark.parametrize("link, message", [
    (dict(parent=3), r"links\[2\]\.parent must be -1 \(the world\) or the index of a link listed before it "
                     r"\(0\.\.1\), got 3"),
    (dict(parent=2), r"links\[2\]\.parent .* got 2: list every link after its parent"),
])
def test_a_parent_that_is_not_listed_before_is_refused(link, message):
    with pytest.raises(ValueError, match=message):
        Chain([Link("revolute", 1.0, 1.0), Link("revolute", 1.0, 1.0), Link("revolute", 1.0, 1.0, **link)])


@pytest.mark.parametrize("kw, error, message", [
    (dict(parent=-2), ValueError, "Link.parent must be None .* -1 \\(the world\\)"),
    (dict(parent=True), ValueError, "Link.parent must be"),
    (dict(parent=1.5), ValueError, "Link.parent must be"),
    (dict(attach=(1.0,)), ValueError, "Link.attach must be a point \\(x, z\\) of two real numbers, got shape \\(1,\\)"),
    (dict(attach=(1.0, 2.0, 3.0)), ValueError, "Link.attach must be a point"),
    (dict(attach=1.0), TypeError, "Link.attach must be a point \\(x, z\\)"),
    (dict(attach="top"), TypeError, "Link.attach must be a point"),
    (dict(attach=(0.0, float("nan"))), ValueError, "Link.attach must be finite"),
    (dict(stiffness=-1.0), ValueError, "Link.stiffness must be >= 0"),
    (dict(sense=0), ValueError, "Link.sense must be 1 or -1"),
])
def test_bad_tree_fields_are_refused_by_name(kw, error, message):
    with pytest.raises(error, match=message):
        Link("revolute", 1.0, 1.0, **kw)


def test_a_reversed_slide_is_refused_with_the_way_out():
    with pytest.raises(ValueError, match="sense must be 1 for a prismatic joint; reverse a slide by turning its axis"):
        Link("prismatic", 1.0, sense=-1)


def test_a_joint_that_moves_nothing_in_its_subtree_is_refused():
    """A hinge whose subtree is massless (a branch of zero mass and inertia) makes M singular everywhere."""
    with pytest.raises(ValueError, match="revolute joint 2 moves no mass.*links \\[2\\]"):
        Chain([Link("revolute", 1.0, 1.0), Link("revolute", 1.0, 1.0), Link("revolute", 0.0, 1.0, parent=0)])
