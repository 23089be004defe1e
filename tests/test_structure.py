"""Skip what a scene doesn't need, measured on the traced program.

The forward dynamics are traced with ``jax.make_jaxpr`` with the chain's parameters as *inputs*
(so every parameter leaf is an input variable of the jaxpr and its uses can be followed), dead
code is removed (as XLA would), and the remaining equations are counted by primitive name.
"""

import collections

import jax
import jax.numpy as jnp
import pytest
from jax.extend import core as jcore

import lagrange as lg
from lagrange.chain import Chain, Link


def _sub_jaxprs(eqn):
    for v in eqn.params.values():
        for x in v if isinstance(v, (tuple, list)) else (v,):
            if isinstance(x, jcore.ClosedJaxpr):
                yield x.jaxpr
            elif isinstance(x, jcore.Jaxpr):
                yield x


def live_eqns(jaxpr):
    """Equations whose outputs reach the jaxpr's outputs (dead-code elimination), recursively."""
    live = {v for v in jaxpr.outvars if isinstance(v, jcore.Var)}
    kept = []
    for eqn in reversed(jaxpr.eqns):
        if any(v in live for v in eqn.outvars):
            kept.append(eqn)
            live.update(v for v in eqn.invars if isinstance(v, jcore.Var))
    out = []
    for eqn in reversed(kept):
        out.append(eqn)
        for sub in _sub_jaxprs(eqn):
            out.extend(live_eqns(sub))
    return out


class Traced:
    """The live equations of ``forward_dynamics(chain, q, qd, u)`` and its input variables."""

    def __init__(self, chain):
        self.chain = chain
        n, m = chain.n, chain.m
        args = (chain, jnp.zeros(n), jnp.zeros(n), jnp.zeros(m))
        closed = jax.make_jaxpr(lambda c, q, qd, u: lg.forward_dynamics(c, q, qd, u if c.m else None))(*args)
        self.jaxpr = closed.jaxpr
        self.eqns = live_eqns(self.jaxpr)
        self.counts = collections.Counter(e.primitive.name for e in self.eqns)
        leaves = jax.tree_util.tree_leaves(args)
        assert len(leaves) == len(self.jaxpr.invars)
        self._invar = {id(leaf): var for leaf, var in zip(leaves, self.jaxpr.invars)}
        self.q = self.jaxpr.invars[len(leaves) - 3]
        self.u = self.jaxpr.invars[len(leaves) - 1]

    def invar(self, leaf):
        return self._invar[id(leaf)]

    def consumers(self, var, through=("slice", "squeeze")):
        """Primitive names of the live equations that use ``var`` (following pure extraction ops)."""
        vars_, names = {var}, []
        for eqn in self.eqns:
            if any(v in vars_ for v in eqn.invars if isinstance(v, jcore.Var)):
                if eqn.primitive.name in through:
                    vars_.update(eqn.outvars)
                else:
                    names.append(eqn.primitive.name)
        return names

    def coordinate_uses(self, i):
        """Primitive names of the live equations that use q_i."""
        vars_, names = set(), []
        for eqn in self.eqns:
            ins = [v for v in eqn.invars if isinstance(v, jcore.Var)]
            name = eqn.primitive.name
            if name == "slice" and ins and ins[0] is self.q:
                if tuple(eqn.params["start_indices"]) == (i,):
                    vars_.update(eqn.outvars)
            elif name == "squeeze" and ins and ins[0] in vars_:
                vars_.update(eqn.outvars)
            elif any(v in vars_ for v in ins):
                names.append(name)
        return set(names)

    def trig(self):
        return self.counts["sin"] + self.counts["cos"]

    def total(self):
        return sum(self.counts.values())


def _is_literal(x, value):
    return isinstance(x, jcore.Literal) and float(x.val) == value


def test_no_trivial_arithmetic():
    """No multiplication by a literal 0 or 1 and no addition of a literal 0 is left in the acrobot's
    program: the 0/1 structure of the derivation was folded at trace time."""
    for chain in (lg.systems.acrobot(), lg.systems.cartpole(), lg.systems.double_cartpole()):
        for eqn in Traced(chain).eqns:
            if eqn.primitive.name == "mul":
                assert not any(_is_literal(x, 0.0) or _is_literal(x, 1.0) for x in eqn.invars), eqn
            if eqn.primitive.name in ("add", "sub"):
                assert not any(_is_literal(x, 0.0) for x in eqn.invars), eqn


def test_acrobot_has_no_damping_ops():
    plain, damped = Traced(lg.systems.acrobot()), Traced(lg.systems.acrobot(damping=0.1))
    assert plain.chain.damping is None  # structurally absent: no leaf at all
    # positive control: the measurement does see damping where it exists ...
    assert damped.consumers(damped.invar(damped.chain.damping))
    # ... and each damped joint costs at least a multiply (b qd) and an add, which the undamped
    # acrobot does not pay (had it computed 0 * qd, the mul counts would be equal)
    assert damped.counts["mul"] >= plain.counts["mul"] + 2
    assert damped.counts["add"] + damped.counts["sub"] >= plain.counts["add"] + plain.counts["sub"] + 2
    assert plain.total() < damped.total()


def test_zero_gravity_has_no_gravity_ops():
    """With gravity = 0 the acrobot needs only sin q2 and cos q2 (for M and the velocity terms);
    sin q1 and sin(q1 + q2) exist only for gravity and are gone."""
    g, g0 = Traced(lg.systems.acrobot()), Traced(lg.systems.acrobot(gravity=0.0))
    assert g0.chain.gravity is None
    assert g.consumers(g.invar(g.chain.gravity))  # positive control
    assert g0.trig() == 2, dict(g0.counts)
    assert g.trig() == 4
    assert g0.counts["mul"] < g.counts["mul"] and g0.total() < g.total()


def test_no_armature_ops():
    links = lambda a: [Link("revolute", 2.5, 1.0, armature=a), Link("revolute", 2.5, 1.0, armature=a, gear=25.0)]
    plain, arm = Traced(Chain(links(0.0))), Traced(Chain(links(0.1)))
    assert plain.chain.armature is None
    assert arm.consumers(arm.invar(arm.chain.armature))  # positive control
    # one add on each diagonal entry of M
    assert arm.counts["add"] >= plain.counts["add"] + 2
    assert plain.total() < arm.total()


@pytest.mark.parametrize(
    "joints",
    [("revolute", "revolute"), ("revolute", "revolute", "revolute"), ("prismatic", "revolute"),
     ("revolute", "prismatic", "revolute"), ("revolute", "revolute", "prismatic")],
    ids=["RR", "RRR", "PR", "RPR", "RRP"],
)
def test_prismatic_terms_only_where_there_is_a_prismatic_joint(joints):
    """A revolute coordinate only enters angle sums and their sines/cosines. A prismatic coordinate
    is a length: after a revolute joint it multiplies a direction (q_i e(phi)), so it feeds a
    multiplication; as the base joint along x (a cart) the dynamics do not depend on it at all
    (translation invariance), so it must not appear."""
    t = Traced(Chain([Link(j, 1.0, 1.0) for j in joints]))
    for i, joint in enumerate(joints):
        uses = t.coordinate_uses(i)
        if joint == "revolute":
            assert uses and uses <= {"add", "sub", "neg", "sin", "cos"}, (i, uses)
        elif i == 0:
            assert uses == set(), (i, uses)
        else:
            assert "mul" in uses, (i, uses)


def test_prismatic_axis_zero_costs_no_rotation():
    """A prismatic joint along its parent's normal (axis 0) needs no rotation of the slide direction."""
    straight = Traced(Chain([Link("revolute", 1.0, 1.0), Link("prismatic", 1.0, 1.0)]))
    tilted = Traced(Chain([Link("revolute", 1.0, 1.0), Link("prismatic", 1.0, 1.0, axis=0.3)]))
    assert straight.total() < tilted.total()


def test_unactuated_joints_have_no_actuation_ops():
    """The acrobot's B has one non-zero: u is used by exactly one multiplication (gear * u), not a
    dense B @ u; a chain with no actuated joint has no such op at all."""
    act = Traced(lg.systems.acrobot())
    assert act.consumers(act.u) == ["mul"]
    assert act.consumers(act.invar(act.chain.gear)) == ["mul"]
    passive = Traced(lg.systems.n_link_pendulum(2, mass=2.5))  # the acrobot without its motor
    assert lg.systems.n_link_pendulum(2).gear is None
    assert passive.counts["mul"] < act.counts["mul"]
    assert passive.total() < act.total()
    # the cartpole and double cartpole: one actuated joint of 2 and 3
    for c in (lg.systems.cartpole(), lg.systems.double_cartpole()):
        t = Traced(c)
        assert t.consumers(t.u) == ["mul"]


def test_acrobot_trigonometry():
    """The acrobot's forward dynamics evaluate 4 sines/cosines: cos q2 (in M), sin q2 (velocity
    terms), sin q1 and sin(q1 + q2) (gravity); a hand-written version needs the same 4."""
    t = Traced(lg.systems.acrobot())
    assert t.trig() == 4, dict(t.counts)
