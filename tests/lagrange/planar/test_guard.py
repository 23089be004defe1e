"""The guard of the planar backend: every planar model run both ways, the planar backend (the unrolled derivation or
the recursive algorithms on the lowered chain) and the general rigid-body algorithms forced on the same tree
(``general=True``), agree to 1e-12: the mass matrix, the bias forces and the accelerations at random states, a 50-step
rollout and its gradient with respect to the initial state and the controls.

The models: the catalogue (the unrolled derivation and, from ``RECURSIVE_MIN`` links, the recursive one), the
README's biped (contact and limits), DFlex's hopper (contact, limits, armature, damping), Gymnasium's planar models
as ``from_mjcf`` reads them (body for body, several joints in a body, joint anchors and ``ref``, which the lowering
carries), and a chain with frame offsets, a tilted slide, a reversed hinge, springs and a clamped motor.
Error = ``max|a - b| / max(1, max|b|)``.
"""

import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.dynamics import backend
from lagrange.interop.mjcf import from_mjcf
from lagrange.planar.lower import lower
from lagrange.planar.model import AbstractPlanar
from lagrange.rbda.backend import General
from lagrange.tasks.locomotion import hopper_chain
from tests.helpers import rel

EXACT = 1e-12
GYM = pathlib.Path(__import__("gymnasium").__file__).parent / "envs/mujoco/assets"


def biped():
    """The README's biped: a floating base (x, z, pitch), two legs with limited joints and feet that touch."""
    hip = dict(parent=2, offset=np.pi, range=(-1.0, 1.0), damping=0.5, gear=50.0)
    knee = dict(range=(-1.5, 0.0), gear=30.0, contacts=[(0.0, -0.4, 0.03)])
    return Chain([
        Link("prismatic", 0.0), Link("prismatic", 0.0, axis=np.pi / 2),
        Link("revolute", 8.0, 0.5, inertia=0.4, offset=np.pi),
        Link("revolute", 2.0, 0.4, attach=(0.0, 0.0), **hip), Link("revolute", 1.0, 0.4, **knee),
        Link("revolute", 2.0, 0.4, attach=(-0.1, 0.0), **hip), Link("revolute", 1.0, 0.4, **knee),
    ], contact=lg.PenaltyContact(ke=2e4, kd=1e3, kf=1e3, mu=0.9, ground=-0.83),
       limits=lg.PenaltyLimits(ke=1e3, kd=10.0))


def frames():
    """Offsets, a tilted slide, a reversed hinge off the line, springs and a clamped motor."""
    return Chain([Link("revolute", 1.0, 0.5, offset=0.3, com_normal=0.1, stiffness=2.0, springref=0.2),
                  Link("prismatic", 0.5, 0.2, axis=0.7, offset=-1.1, damping=0.3, armature=0.05),
                  Link("revolute", 0.7, 0.6, sense=-1, offset=2.5, parent=0, attach=(0.1, -0.2), gear=3.0,
                       control_range=(-1.0, 1.0))], gravity=7.0)


def _gym(name, **kw):
    return lambda: from_mjcf(GYM / name, **kw)


MODELS = {
    "acrobot": lg.systems.acrobot,
    "cartpole": lg.systems.cartpole,
    "double_cartpole": lg.systems.double_cartpole,
    "pendulum5": lambda: lg.systems.n_link_pendulum(5, gear=1.0, damping=0.1),
    "frames": frames,
    "biped": biped,
    "dflex_hopper": hopper_chain,
    "gym_hopper": _gym("hopper.xml", limits=lg.PenaltyLimits(1e3, 10.0), contact=lg.PenaltyContact(2e4, 1e3, 1e3, 0.9)),
    "gym_cheetah": _gym("half_cheetah.xml", limits="ignore", contact="ignore"),
    "gym_walker": _gym("walker2d_v5.xml", limits="ignore", contact="ignore"),
    "gym_reacher": _gym("reacher.xml", limits="ignore", contact="ignore"),
    "gym_double_pendulum": _gym("inverted_double_pendulum.xml", limits="ignore"),
}


def _both(tree, q, qd, u, q0, qd0, us):
    """Everything both ways in one compiled program: ``{quantity: (planar, general)}``."""
    out = {}
    for general in (False, True):
        b = backend(tree, general=general)
        per_state = jax.vmap(lambda q, qd, u: (b.mass_matrix(q), b.bias_forces(q, qd),
                                               b.forward_dynamics(q, qd, u)))(q, qd, u)

        def final(q0, us):
            traj = lg.simulate(tree, q0, qd0, us, 0.002, lg.SemiImplicitEuler(), general=general, check=False)
            return jnp.sum(traj.q[-1] * jnp.arange(1, tree.nq + 1)) + jnp.sum(traj.qd[-1] ** 2), traj

        (value, traj), grads = jax.value_and_grad(final, argnums=(0, 1), has_aux=True)(q0, us)
        for name, x in zip(("M", "bias", "qdd", "rollout q", "rollout qd", "value", "d/dq0", "d/du"),
                           (*per_state, traj.q, traj.qd, value, *grads)):
            out.setdefault(name, []).append(x)
    return out


@pytest.mark.parametrize("name", list(MODELS))
def test_planar_models_agree_both_ways(name):
    tree = MODELS[name]()
    assert tree.planar and isinstance(backend(tree), AbstractPlanar) and isinstance(backend(tree, general=True),
                                                                                 General)
    rng = np.random.default_rng(len(name))
    k = 4
    q0 = np.asarray(tree.neutral()) + rng.uniform(-0.2, 0.2, tree.nq)
    q = jnp.asarray(q0 + rng.uniform(-1.0, 1.0, (k, tree.nq)))
    qd = jnp.asarray(rng.uniform(-2.0, 2.0, (k, tree.nv)))
    u = jnp.asarray(rng.uniform(-1.0, 1.0, (k, tree.m)))
    us = jnp.asarray(rng.uniform(-0.5, 0.5, (50, tree.m)))
    out = jax.jit(lambda *x: _both(tree, *x))(q, qd, u, jnp.asarray(q0), jnp.zeros(tree.nv), us)
    errors = {quantity: rel(planar, general) for quantity, (planar, general) in out.items()}
    print(f"{name}: worst {max(errors.values()):.2g} ({max(errors, key=errors.get)})")
    for quantity, (_, general) in out.items():
        assert np.all(np.isfinite(np.asarray(general))), quantity
        assert errors[quantity] <= EXACT, (quantity, errors[quantity])


def _lowered_inside_jit(tree) -> bool:
    """Whether the dispatch lowers ``tree`` to the planar backend while its parameters are traced (``filter_jit``)."""
    seen = []

    def f(t):
        seen.append(lower(t) is not None)
        return lg.mass_matrix(t, jnp.zeros(t.nq))

    eqx.filter_jit(f)(tree)
    return seen[0]


def test_traced_parameters_keep_the_planar_backend_only_where_it_is_exact():
    """A chain's gravity stays along the plane's -z when traced (its other components are structurally zero); a
    tree with a concrete gravity tilted in its plane is lowered (the plane's z follows it), but with the gravity traced
    its in-plane tilt is unknown and the general algorithms run; motors listed out of joint order are the general
    algorithms' too. Each way the accelerations are the general algorithms'."""
    chain = frames()
    assert chain.gravity_support == (False, False, True) and _lowered_inside_jit(chain)
    tilted = lg.Tree(chain.bodies, (0.5, 0.0, -9.81), motors=chain.motors)
    swapped = lg.Tree(chain.bodies, chain.gravity,
                      motors=[lg.Motor(2, 1.5), lg.Motor(0, 2.0, control_range=(-1.0, 1.0))])
    assert lower(tilted) is not None and not _lowered_inside_jit(tilted) and lower(swapped) is None
    q, qd = jnp.asarray([0.3, -0.1, 0.7]), jnp.asarray([0.5, 0.2, -1.0])
    for tree, u in ((tilted, jnp.asarray([0.4])), (swapped, jnp.asarray([0.4, -2.0]))):
        general = lg.dynamics.prepare(tree, general=True).forward_dynamics(q, qd, u)
        concrete = lg.forward_dynamics(tree, q, qd, u)
        traced = eqx.filter_jit(lg.forward_dynamics)(tree, q, qd, u)
        assert rel(concrete, general) <= EXACT and rel(traced, general) <= EXACT


def test_slides_along_three_directions_are_not_planar_and_run_on_the_general_algorithms():
    """Slides only, no common plane: ``Tree.planar`` is false (the plane's search used to raise StopIteration) and a
    free point mass falls with gravity."""
    slides = [lg.Slide(axis) for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))]
    tree = lg.Tree([lg.Body(2.0, np.eye(3), np.zeros(3), joints=slides)], (0.3, 0.0, -9.81))
    assert not tree.planar and isinstance(backend(tree), General)
    assert rel(lg.forward_dynamics(tree, jnp.zeros(3), jnp.zeros(3)), jnp.asarray([0.3, 0.0, -9.81])) <= EXACT
