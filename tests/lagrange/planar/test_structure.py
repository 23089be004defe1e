"""Skip what a scene doesn't need, measured on the traced program.

The forward dynamics are traced with ``jax.make_jaxpr`` with the chain closed over, as the trainers and the
benchmarks compile it (its parameters constants, folded while tracing, and its structure static: which terms exist is
the planar backend's reading of the tree, :func:`lagrange.planar.lower.lower`), dead code is removed (as XLA would),
and the remaining equations are counted by primitive name. ``inputs=True`` traces the parameters as inputs instead
(a gradient with respect to the tree), for the comparison of the two.
"""

import collections

import equinox as eqx
import jax
import jax.numpy as jnp
import pytest
from jax.extend import core as jcore

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.planar.lower import lower as planar


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
    """The live equations of ``forward_dynamics(chain, q, qd, u, check=False)`` and its input variables: the program of
    the dynamics, without the run-time checks of traced parameters and pivots (``check=True``), which are
    :func:`lagrange.model.checks.check_parameters`' and ``tests/lagrange/model/test_chain.py``'s concern."""

    def __init__(self, chain, inputs: bool = False):
        self.chain, self.links = chain, planar(chain)
        n, m = chain.nv, chain.m
        states = (jnp.zeros(n), jnp.zeros(n), jnp.zeros(m))
        if inputs:
            closed = jax.make_jaxpr(lambda c, q, qd, u: lg.forward_dynamics(c, q, qd, u if c.m else None,
                                                                            check=False))(chain, *states)
        else:
            closed = jax.make_jaxpr(lambda q, qd, u: lg.forward_dynamics(chain, q, qd, u if chain.m else None,
                                                                         check=False))(*states)
        self.jaxpr = closed.jaxpr
        self.eqns = live_eqns(self.jaxpr)
        self.counts = collections.Counter(e.primitive.name for e in self.eqns)
        self.q, self.u = self.jaxpr.invars[-3], self.jaxpr.invars[-1]

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
    assert plain.links.damping is None and damped.links.damping is not None  # structurally absent: no term at all
    # each damped joint costs at least a multiply (b qd) and an add, which the undamped
    # acrobot does not pay (had it computed 0 * qd, the mul counts would be equal)
    assert damped.counts["mul"] >= plain.counts["mul"] + 2
    assert damped.counts["add"] + damped.counts["sub"] >= plain.counts["add"] + plain.counts["sub"] + 2
    assert plain.total() < damped.total()


def test_zero_gravity_has_no_gravity_ops():
    """With gravity = 0 the acrobot needs only sin q2 and cos q2 (for M and the velocity terms);
    sin q1 and sin(q1 + q2) exist only for gravity and are gone."""
    g, g0 = Traced(lg.systems.acrobot()), Traced(lg.systems.acrobot(gravity=0.0))
    assert g0.links.gravity is None and g.links.gravity is not None
    assert g0.trig() == 2, dict(g0.counts)
    assert g.trig() == 4
    assert g0.counts["mul"] < g.counts["mul"] and g0.total() < g.total()


def test_no_armature_ops():
    links = lambda a: [Link("revolute", 2.5, 1.0, armature=a), Link("revolute", 2.5, 1.0, armature=a, gear=25.0)]
    plain, arm = Traced(Chain(links(0.0))), Traced(Chain(links(0.1)))
    assert plain.links.armature is None and arm.links.armature is not None
    # an add on each diagonal entry of M that depends on q (M_11; M_22 is a constant, the armature folds into it)
    assert arm.counts["add"] >= plain.counts["add"] + 1
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
    assert act.consumers(act.u) == ["mul"]  # by the gear, a literal
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


STRUCTURES = {
    "acrobot": lg.systems.acrobot(),
    "cartpole": lg.systems.cartpole(),
    "double cartpole": lg.systems.double_cartpole(),
    "passive double pendulum": lg.systems.n_link_pendulum(2),
    "4-link pendulum": lg.systems.n_link_pendulum(4),
    "damped acrobot": lg.systems.acrobot(damping=0.1),
    "RPR, tilted slide": Chain([Link("revolute", 1.0, 1.0), Link("prismatic", 1.0, 1.0, axis=0.3, gear=2.0),
                                Link("revolute", 1.0, 1.0, gear=1.0)]),
    "RRP": Chain([Link("revolute", 1.0, 1.0), Link("revolute", 1.0, 1.0), Link("prismatic", 1.0, 1.0, gear=1.0)]),
}


@pytest.mark.parametrize("name", list(STRUCTURES))
def test_no_negation_reaches_xla(name):
    """Every sign of the derivation is folded while tracing, into a constant factor or by turning an addition into
    a subtraction (``lagrange.math.scalar.negated``): no ``neg`` is left in the forward dynamics, and no ``negate`` in
    the compiled batched RK4 rollout. A negate in a fused RK4 stage can cost it its vectorization on the CPU
    (``python -m research.xla_vectorization``: the cartpole's closed form 1.5-1.9x slower with one)."""
    chain = STRUCTURES[name]
    counts = Traced(chain).counts
    assert counts["neg"] == 0, dict(counts)
    n, m = chain.nv, chain.m
    states = (jnp.zeros((4, n)), jnp.zeros((4, n)))
    if m:  # 4 rollouts of 3 steps
        roll, args = (lambda q, qd, us: lg.simulate(chain, q, qd, us, 0.01).q), (*states, jnp.zeros((4, 3, m)))
    else:
        roll, args = (lambda q, qd: lg.simulate(chain, q, qd, None, 0.01, steps=3).q), states
    hlo = jax.jit(jax.vmap(roll)).lower(*args).compile().as_text()
    assert " negate(" not in hlo
    # positive control: the search finds a negate where one is written
    control = jax.jit(jax.vmap(lambda q: -jnp.sin(q))).lower(jnp.zeros((4, n))).compile().as_text()
    assert " negate(" in control


def test_concrete_parameters_are_folded():
    """A chain closed over by a traced function has concrete parameters: their products are computed while tracing
    and reach the program as literals (``lagrange.dynamics._folded``), which is fewer operations than with the
    parameters as inputs; the values agree, and traced parameters (a gradient with respect to the chain) still flow."""
    chain = lg.systems.double_cartpole()
    q, qd, u = jnp.array([0.3, -1.2, 2.0]), jnp.array([0.5, 1.5, -2.5]), jnp.array([0.4])
    closed = jax.make_jaxpr(lambda q, qd, u: lg.forward_dynamics(chain, q, qd, u))(q, qd, u)
    assert not closed.consts  # no parameter array captured as a run-time constant
    assert len(live_eqns(closed.jaxpr)) < Traced(chain, inputs=True).total()
    folded = jax.jit(lambda q, qd, u: lg.forward_dynamics(chain, q, qd, u))(q, qd, u)
    as_inputs = jax.jit(lg.forward_dynamics)(chain, q, qd, u)
    assert jnp.allclose(folded, as_inputs, rtol=1e-14, atol=0.0)
    dmass = jax.grad(lambda c: lg.forward_dynamics(c, q, qd, u)[1])(chain).mass
    h = 1e-6
    fd = []
    for k in range(chain.nv):
        plus = _bump_mass(chain, k, h)
        minus = _bump_mass(chain, k, -h)
        fd.append((lg.forward_dynamics(plus, q, qd, u)[1] - lg.forward_dynamics(minus, q, qd, u)[1]) / (2 * h))
    assert jnp.allclose(dmass, jnp.array(fd), rtol=1e-7, atol=1e-9), (dmass, fd)


def _bump_mass(chain, k, h):
    return eqx.tree_at(lambda c: c.bodies[k].mass, chain, chain.bodies[k].mass + h)


def test_symbolic_signs_are_exact():
    """``lagrange.math.scalar`` keeps signs symbolic. Negation commutes exactly with IEEE rounding, so every combination
    of ``negated``, ``neg``, ``add``, ``sub``, ``mul`` and ``div`` over constants, arrays and negated arrays, two levels
    deep and materialised by ``as_array``, equals the same arithmetic done eagerly with ``jax.numpy`` to the last bit
    (not NumPy's: XLA divides by a constant as a multiplication by its reciprocal)."""
    import itertools

    import numpy as np

    from lagrange.math import scalar as s

    rng = np.random.default_rng(0)
    x, y = jnp.asarray(rng.standard_normal(7)), jnp.asarray(rng.standard_normal(7) + 3.0)
    leaves = [(x, x), (y, y), (2.5, 2.5), (-1.0, -1.0), (1.0, 1.0), (0.0, 0.0),
              (s.negated(x), -x), (s.negated(y), -y), (s.neg(y), -y)]
    ops = [(s.add, jnp.add), (s.sub, jnp.subtract), (s.mul, jnp.multiply), (s.div, jnp.divide)]
    level1 = []
    for (a, na), (b, nb) in itertools.product(leaves, repeat=2):
        for f, nf in ops:
            if not (f is s.div and np.all(nb == 0.0)):
                level1.append((f(a, b), nf(na, nb)))
    level1 += [(s.negated(r), -nr) for r, nr in level1[::7]] + [(s.neg(r), -nr) for r, nr in level1[3::7]]
    checked = 0
    for (a, na), (b, nb) in itertools.product(level1[::5], leaves):
        for f, nf in ops:
            if f is s.div and np.any(np.asarray(nb) == 0.0):
                continue
            got = np.asarray(s.as_array(f(a, b), like=x))
            want = np.broadcast_to(np.asarray(nf(na, nb), dtype=np.float64), x.shape)
            assert np.array_equal(got, want, equal_nan=True), (f.__name__, a, b)
            checked += 1
    assert checked > 1000
