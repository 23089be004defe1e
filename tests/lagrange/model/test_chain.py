"""Bad input: every mistake listed in the issue raises ValueError/TypeError naming the field (and
the allowed values), at construction or trace time; a non-finite state at run time is reported,
never returned silently."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.planar.lower import lower as planar

NAN, INF = math.nan, math.inf


def acrobot():
    return lg.systems.acrobot()


# ------------------------------------------------------------------ link parameters

# (field, bad value, message pattern): the pattern names the field and the allowed range
NONNEGATIVE = ["mass", "length", "inertia", "damping", "armature"]
BAD_VALUES = (
    [(f, -1.0, rf"Link\.{f} must be >= 0") for f in NONNEGATIVE]
    + [(f, NAN, rf"Link\.{f} must be finite") for f in NONNEGATIVE + ["gear", "com"]]
    + [(f, INF, rf"Link\.{f} must be finite") for f in NONNEGATIVE + ["gear", "com"]]
    + [(f, -INF, rf"Link\.{f} must be finite") for f in ["mass", "gear"]]
)


def _link(field, value):
    kwargs = dict(mass=1.0, length=1.0)
    kwargs[field] = value
    return Link("revolute", **kwargs)


@pytest.mark.parametrize("field,value,pattern", BAD_VALUES, ids=[f"{f}={v}" for f, v, _ in BAD_VALUES])
def test_bad_link_value(field, value, pattern):
    with pytest.raises(ValueError, match=pattern):
        _link(field, value)


def test_negative_gear():
    """The issue lists a negative gear as bad input (the sign of an actuator belongs in the policy)."""
    with pytest.raises(ValueError, match=r"Link\.gear"):
        _link("gear", -1.0)


# None is a non-numeric value too, except where it means something (default com/inertia, no gear)
NON_NUMERIC = [(f, v) for f in NONNEGATIVE + ["com", "gear"] for v in ("heavy", True, object())] + [
    (f, None) for f in ("mass", "length", "damping", "armature")
]


@pytest.mark.parametrize("field,value", NON_NUMERIC, ids=[f"{f}={type(v).__name__}" for f, v in NON_NUMERIC])
def test_non_numeric_link_value(field, value):
    with pytest.raises(TypeError, match=rf"Link\.{field} must be a real number"):
        Chain([_link(field, value)])


def test_array_valued_link_parameter():
    with pytest.raises(ValueError, match=r"Link\.mass must be a scalar"):
        Link("revolute", jnp.ones(2), 1.0)


def test_values_from_the_catalogue_are_checked_too():
    with pytest.raises(ValueError, match=r"Link\.mass must be >= 0"):
        lg.systems.acrobot(masses=(2.5, -1.0))
    with pytest.raises(ValueError, match=r"Link\.length must be finite"):
        lg.systems.cartpole(pole_length=NAN)


@pytest.mark.parametrize("joint", ["spherical", "Revolute", 3, None])
def test_unknown_joint_kind(joint):
    with pytest.raises(ValueError, match=r"Link\.joint must be one of \('revolute', 'prismatic'\)"):
        Link(joint, 1.0, 1.0)


# ------------------------------------------------------------------ chain

_COMPILES: list[str] = []
jax.monitoring.register_event_duration_secs_listener(
    lambda event, secs, **kw: _COMPILES.append(event) if event.startswith("/jax/core/compile") else None
)


def _jax_work(build):
    """The JAX compile events while ``build()`` runs, with JAX's caches cleared first: any JAX operation, traced or
    run eagerly, is traced and compiled then (an eager op is a small jitted program), so none means none ran."""
    jax.clear_caches()
    start = len(_COMPILES)
    build()
    return _COMPILES[start:]


def test_building_a_chain_computes_nothing():
    """Building a chain checks and stacks its parameters, and runs no JAX computation: no dynamics (formerly a
    singularity check computed M at three configurations) and no JAX operation."""
    arrays = dict(mass=jnp.asarray(2.0), length=np.float32(0.5))  # JAX and NumPy scalars are accepted too
    rebuilt = acrobot().links()
    assert _jax_work(lambda: jnp.stack([jnp.asarray(1.0), jnp.asarray(2.0)]))  # positive control: an eager op counts
    for build in (
        acrobot,
        lambda: lg.systems.double_cartpole(damping=0.1),
        lambda: lg.systems.n_link_pendulum(6, gear=1.0),
        lambda: Chain([Link("prismatic", 1.0, axis=0.3, armature=0.1, gear=2.0), Link("revolute", **arrays)]),
        lambda: Chain(rebuilt),
    ):
        assert _jax_work(build) == []
    chain = Chain([Link("revolute", **arrays)])
    assert isinstance(chain.mass, jax.Array) and chain.mass.dtype == jnp.asarray(1.0).dtype
    links = planar(chain)  # the planar backend's reading: a thin rod's inertia, the centre of mass half way
    assert float(links.inertia[0]) == 2.0 * 0.5**2 / 12 and float(links.com[0]) == 0.25
    assert float(chain.bodies[0].inertia[1, 1]) == 2.0 * 0.5**2 / 12 and float(chain.bodies[0].com[2]) == -0.25


def test_chain_built_from_traced_parameters():
    """Parameters traced by ``jax.grad`` stack with ``jax.numpy`` (the trace records them), and the gradient flows."""

    def tip_height(mass):
        chain = Chain([Link("revolute", 1.0, 1.0), Link("revolute", mass, 1.0, gear=1.0)])
        return lg.forward_dynamics(chain, jnp.array([0.3, 0.2]), jnp.zeros(2), jnp.array([1.0]))[1]

    value_and_grad = jax.jit(jax.value_and_grad(tip_height))  # one compiled program gives the values and the gradient
    h = 1e-6
    fd = (value_and_grad(2.0 + h)[0] - value_and_grad(2.0 - h)[0]) / (2 * h)
    assert jnp.allclose(value_and_grad(2.0)[1], fd, rtol=1e-7)


def test_no_links():
    with pytest.raises(ValueError, match=r"Chain\.links must contain at least one Link"):
        Chain([])
    with pytest.raises(ValueError, match=r"n must be an integer >= 1"):
        lg.systems.n_link_pendulum(0)


def test_links_that_are_not_links():
    with pytest.raises(TypeError, match=r"Chain\.links\[1\] must be a lagrange\.chain\.Link"):
        Chain([Link("revolute", 1.0, 1.0), {"joint": "revolute"}])
    with pytest.raises(TypeError, match=r"Chain\.links must be a sequence of Link"):
        Chain(Link("revolute", 1.0, 1.0))


def test_singular_mass_matrix():
    """A joint that moves nothing at any configuration (its diagonal of M is identically zero, so M is singular
    everywhere) is refused from the parameters alone, naming the joint, the links and the fix."""
    # a massless, inertia-less tip link
    with pytest.raises(ValueError, match=r"singular mass matrix: revolute joint 1 moves no mass.*"
                                         r"links \[1\] have zero mass and zero inertia.*armature > 0"):
        Chain([Link("revolute", 1.0, 1.0), Link("revolute", 0.0, 1.0, inertia=0.0)])
    # a massless prismatic cart carrying nothing: its inertia would not help, a slide rotates nothing
    with pytest.raises(ValueError, match=r"singular mass matrix: prismatic joint 0 moves no mass"):
        Chain([Link("prismatic", 0.0, inertia=1.0)])
    # a point mass on the joint's own axis, and one on the axis through a link of zero length
    with pytest.raises(ValueError, match=r"singular mass matrix: revolute joint 0.*"
                                         r"links \[0\] have zero inertia and their centre of mass on joint 0's axis"):
        Chain([Link("revolute", 1.0, 1.0, com=0.0, inertia=0.0)])
    with pytest.raises(ValueError, match=r"singular mass matrix: revolute joint 0.*links \[0, 1\] have zero inertia"):
        Chain([Link("revolute", 1.0, 0.0, com=0.0, inertia=0.0), Link("revolute", 1.0, 1.0, com=0.0, inertia=0.0)])


def test_massless_link_with_inertia_or_armature_is_fine():
    """The check is not over-eager: inertia or armature alone make M regular."""
    Chain([Link("revolute", 1.0, 1.0), Link("revolute", 0.0, 1.0, inertia=0.1)])
    Chain([Link("revolute", 1.0, 1.0), Link("revolute", 0.0, 1.0, inertia=0.0, armature=0.1)])
    # joint 0 moves a point mass off its axis, through a link of non-zero length or a slide between
    Chain([Link("revolute", 1.0, 0.5, com=0.0, inertia=0.0), Link("revolute", 1.0, 1.0, com=0.0, inertia=0.1)])
    Chain([Link("revolute", 0.0, 0.0, com=0.0, inertia=0.0), Link("prismatic", 1.0, 0.0, com=0.0, inertia=0.0),
           Link("revolute", 1.0, 1.0, com=0.5, inertia=0.0)])


@pytest.mark.parametrize("gravity", [NAN, INF, -INF])
def test_non_finite_gravity(gravity):
    with pytest.raises(ValueError, match=r"Chain\.gravity must be finite"):
        Chain([Link("revolute", 1.0, 1.0)], gravity=gravity)
    with pytest.raises(ValueError, match=r"Chain\.gravity must be finite"):
        lg.systems.pendulum(gravity=gravity)


@pytest.mark.parametrize("gravity", ["down", None, (0.0, -9.81)], ids=["str", "None", "vector"])
def test_non_numeric_gravity(gravity):
    with pytest.raises((TypeError, ValueError), match=r"Chain\.gravity must be a (real number|scalar)"):
        Chain([Link("revolute", 1.0, 1.0)], gravity=gravity)


# ------------------------------------------------------------------ shapes of q, qd, u


@pytest.mark.parametrize(
    "fn",
    [
        lambda c, q, qd, u: lg.mass_matrix(c, q),
        lambda c, q, qd, u: lg.gravity_forces(c, q),
        lambda c, q, qd, u: lg.bias_forces(c, q, qd),
        lambda c, q, qd, u: lg.forward_dynamics(c, q, qd, u),
        lambda c, q, qd, u: lg.inverse_dynamics(c, q, qd, qd),
        lambda c, q, qd, u: lg.energy(c, q, qd),
        lambda c, q, qd, u: lg.step(c, q, qd, u, 0.01),
    ],
    ids=["mass_matrix", "gravity_forces", "bias_forces", "forward_dynamics", "inverse_dynamics", "energy", "step"],
)
def test_wrong_shape_q(fn):
    c, ok = acrobot(), jnp.zeros(2)
    for bad in (jnp.zeros(3), jnp.zeros(()), jnp.zeros((4, 1))):
        with pytest.raises(ValueError, match=r"\bq must have shape \(\.\.\., 2\)"):
            fn(c, bad, ok, jnp.zeros(1))


@pytest.mark.parametrize(
    "fn",
    [
        lambda c, q, qd, u: lg.bias_forces(c, q, qd),
        lambda c, q, qd, u: lg.forward_dynamics(c, q, qd, u),
        lambda c, q, qd, u: lg.energy(c, q, qd),
        lambda c, q, qd, u: lg.step(c, q, qd, u, 0.01),
    ],
    ids=["bias_forces", "forward_dynamics", "energy", "step"],
)
def test_wrong_shape_qd(fn):
    c, ok = acrobot(), jnp.zeros(2)
    with pytest.raises(ValueError, match=r"\bqd must have shape \(\.\.\., 2\)"):
        fn(c, ok, jnp.zeros(3), jnp.zeros(1))


def test_wrong_shape_qdd():
    with pytest.raises(ValueError, match=r"\bqdd must have shape \(\.\.\., 2\)"):
        lg.inverse_dynamics(acrobot(), jnp.zeros(2), jnp.zeros(2), jnp.zeros(1))


@pytest.mark.parametrize("u", [jnp.zeros(2), jnp.zeros(())], ids=["(2,)", "()"])
def test_wrong_shape_u(u):
    c, z = acrobot(), jnp.zeros(2)
    with pytest.raises(ValueError, match=r"\bu must have shape \(\.\.\., 1\)"):
        lg.forward_dynamics(c, z, z, u)
    with pytest.raises(ValueError, match=r"\bu must have shape \(\.\.\., 1\)"):
        lg.step(c, z, z, u, 0.01)


def test_control_for_an_unactuated_chain():
    """An unactuated chain takes u=None (or shape (..., 0)); a real control would be dropped silently."""
    c, z = lg.systems.n_link_pendulum(2), jnp.zeros(2)
    with pytest.raises(ValueError, match=r"\bu must have shape \(\.\.\., 0\)"):
        lg.forward_dynamics(c, z, z, jnp.ones(1))


@pytest.mark.parametrize("which", ["q0", "qd0"])
def test_simulate_wrong_shape_state(which):
    c = acrobot()
    args = {"q0": jnp.zeros(2), "qd0": jnp.zeros(2)}
    args[which] = jnp.zeros((1, 2))
    with pytest.raises(ValueError, match=rf"{which} must have shape \(2,\)"):
        lg.simulate(c, args["q0"], args["qd0"], jnp.zeros((3, 1)), 0.01)


@pytest.mark.parametrize("controls", [jnp.zeros(5), jnp.zeros((5, 2)), jnp.zeros((5, 1, 1))],
                         ids=["(5,)", "(5,2)", "(5,1,1)"])
def test_controls_of_wrong_shape(controls):
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"controls must have shape \(T, 1\)"):
        lg.simulate(acrobot(), z, z, controls, 0.01)


def test_policy_returning_wrong_shape():
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"policy must return u of shape \(1,\)"):
        lg.simulate(acrobot(), z, z, lambda t, q, qd: jnp.ones(2), 0.01, steps=3)
    with pytest.raises(ValueError, match=r"steps .* is required with a policy"):
        lg.simulate(acrobot(), z, z, lambda t, q, qd: jnp.ones(1), 0.01)


# ------------------------------------------------------------------ integration settings


@pytest.mark.parametrize("dt", [0.0, -0.01, NAN, INF])
def test_bad_dt(dt):
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"dt must be a finite number > 0"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), dt)
    with pytest.raises(ValueError, match=r"dt must be a finite number > 0"):
        lg.step(acrobot(), z, z, jnp.zeros(1), dt)


def test_non_numeric_dt():
    z = jnp.zeros(2)
    with pytest.raises(TypeError, match=r"dt must be a positive real number"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), "fast")


@pytest.mark.parametrize("substeps", [0, -1, 1.5, True])
def test_bad_substeps(substeps):
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"substeps must be an integer >= 1"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), 0.01, substeps=substeps)


@pytest.mark.parametrize("solver", [lg.RK4(), lg.Euler(), lg.SemiImplicitEuler()], ids=lambda s: type(s).__name__)
def test_rtol_without_an_adaptive_solver(solver):
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"rtol/atol cannot be used.*Tsit5\(\), Dopri5\(\) or Dopri8\(\)"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), 0.01, solver, rtol=1e-6, atol=1e-6)


def test_rtol_without_atol_and_bad_tolerances():
    z = jnp.zeros(2)
    with pytest.raises(ValueError, match=r"needs both rtol and atol"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), 0.01, lg.Dopri5(), rtol=1e-6)
    with pytest.raises(ValueError, match=r"rtol and atol must be > 0"):
        lg.simulate(acrobot(), z, z, jnp.zeros((3, 1)), 0.01, lg.Dopri5(), rtol=-1e-6, atol=1e-6)


def test_simulate_needs_a_chain():
    z = jnp.zeros(2)
    with pytest.raises(TypeError, match=r"tree must be a lagrange\.Tree \(a lagrange\.chain\.Chain is one\)"):
        lg.simulate([Link("revolute", 1.0, 1.0)], z, z, jnp.zeros((3, 1)), 0.01)


# ------------------------------------------------------------------ run time


def test_non_finite_state_is_reported():
    """A huge control drives the state to inf/NaN: simulate raises instead of returning it."""
    z = jnp.zeros(2)
    huge = jnp.full((20, 1), 1e300)
    with pytest.raises(RuntimeError, match=r"non-finite"):
        traj = lg.simulate(acrobot(), z, z, huge, 0.01)
        jax.block_until_ready(traj.q)
    # also under jit, where the controls are only known at run time
    run = eqx.filter_jit(lambda u: lg.simulate(acrobot(), z, z, u, 0.01).q)
    with pytest.raises(RuntimeError, match=r"non-finite"):
        jax.block_until_ready(run(huge))
    # the same program with sane controls runs: the check is not a false alarm
    assert np.all(np.isfinite(np.asarray(run(jnp.zeros((20, 1))))))


def test_singular_configuration_is_reported():
    """A mass matrix singular only at some configurations passes the constructor and is reported where it is met:
    a massless shoulder carrying a point mass (``det M = m2^2 l1^2 l2^2 sin^2 q2``) with the elbow straight. The
    parameters alone cannot show it, nor can a chain edited after construction (``eqx.tree_at``), here a 5-link
    pendulum (the recursive path) given a massless tip."""
    chain = Chain([Link("revolute", 0.0, 1.0, com=1.0, inertia=0.0), Link("revolute", 1.0, 1.0, com=1.0, inertia=0.0)])
    qd = jnp.array([0.1, 0.2])
    with pytest.raises(RuntimeError, match=r"mass matrix is singular.*inertia > 0 or the joints an armature > 0"):
        jax.block_until_ready(lg.forward_dynamics(chain, jnp.array([0.3, 0.0]), qd))
    with pytest.raises(RuntimeError, match=r"mass matrix is singular"):  # in a batch, under jit
        jax.block_until_ready(jax.jit(lambda q: lg.forward_dynamics(chain, q, qd))(jnp.array([[0.3, 0.5], [0.3, 0.0]])))
    assert np.all(np.isfinite(np.asarray(lg.forward_dynamics(chain, jnp.array([0.3, 0.5]), qd))))  # not a false alarm
    five = lg.systems.n_link_pendulum(5)
    tipless = eqx.tree_at(lambda c: (c.bodies[4].mass, c.bodies[4].inertia), five, (np.zeros(()), np.zeros((3, 3))))
    with pytest.raises(RuntimeError, match=r"mass matrix is singular"):
        jax.block_until_ready(lg.forward_dynamics(tipless, jnp.full(5, 0.3), jnp.zeros(5)))
    assert np.all(np.isfinite(np.asarray(lg.forward_dynamics(five, jnp.full(5, 0.3), jnp.zeros(5)))))
    # simulate: the singular step makes the state non-finite, and the message names this cause too
    with pytest.raises(RuntimeError, match=r"non-finite.*singular somewhere on the way"):
        jax.block_until_ready(lg.simulate(chain, jnp.array([0.3, 0.0]), jnp.zeros(2), None, 0.01, steps=3).q)


def test_non_finite_initial_state_is_reported():
    """A NaN initial state or control is refused by name: now when concrete, when run under jit."""
    with pytest.raises(ValueError, match=r"q0 must be finite, got nan at index \(0,\)"):
        lg.simulate(acrobot(), jnp.array([NAN, 0.0]), jnp.zeros(2), jnp.zeros((3, 1)), 0.01)
    with pytest.raises(ValueError, match=r"controls must be finite, got inf at index \(1, 0\)"):
        lg.simulate(acrobot(), jnp.zeros(2), jnp.zeros(2), jnp.array([[0.0], [np.inf], [0.0]]), 0.01)
    run = eqx.filter_jit(lambda qd0: lg.simulate(acrobot(), jnp.zeros(2), qd0, jnp.zeros((3, 1)), 0.01).q)
    with pytest.raises(RuntimeError, match=r"qd0 is not finite"):
        jax.block_until_ready(run(jnp.array([0.0, NAN])))


def _final_angle(chain):
    q = jnp.full(2, 0.1)
    return lg.simulate(chain, q, q, jnp.zeros((3, 1)), 0.01).q[-1, 0]


# the gradient with respect to the whole chain, every parameter traced: one compilation serves every case below
_TRACED_GRAD = eqx.filter_jit(eqx.filter_grad(_final_angle))


_FIELDS = {"mass": lambda c: c.bodies[0].mass, "inertia": lambda c: c.bodies[1].inertia,
           "gear": lambda c: c.motors[0].gear, "gravity": lambda c: c.gravity}


@pytest.mark.parametrize("field, value, message", [
    ("mass", -1.0, r"Chain\.bodies\[0\]\.mass must be >= 0 and finite, got -1\.0"),
    ("inertia", np.diag([0.1, np.nan, 0.1]), r"Chain\.bodies\[1\]\.inertia must be on its diagonal >= 0 and finite"),
    ("gear", -25.0, r"Chain\.motors\[0\]\.gear must be > 0"),
    ("gravity", [0.0, 0.0, float("inf")], r"Chain\.gravity must be finite, got \[0\.0, 0\.0, inf\]"),
])
def test_parameters_set_after_construction_are_checked(field, value, message):
    """A parameter set with ``eqx.tree_at`` skips the constructor: concrete, it is refused when the chain is used
    (simulate, the dynamics, energy), naming the leaf (its body or motor); traced (a fit under ``jit(grad)``), it is
    refused when run (here with every parameter of the chain traced, ``_TRACED_GRAD``: the program is the same for
    every field)."""
    good = lg.systems.acrobot()
    get = _FIELDS[field]
    bad = eqx.tree_at(get, good, np.asarray(value, float))
    q = jnp.full(2, 0.1)
    for use in (lambda c: lg.simulate(c, q, q, jnp.zeros((3, 1)), 0.01), lambda c: lg.mass_matrix(c, q),
                lambda c: lg.forward_dynamics(c, q, q, jnp.zeros(1)), lambda c: lg.energy(c, q, q)):
        with pytest.raises(ValueError, match=message):
            use(bad)

    assert np.all(np.isfinite(get(_TRACED_GRAD(good))))  # a valid one passes
    traced = message.split(" must be")[0] + " must be"
    with pytest.raises(eqx.EquinoxRuntimeError, match=traced):
        _TRACED_GRAD(eqx.tree_at(get, good, jnp.asarray(value, get(good).dtype)))


def test_positions_check_the_length_of_q():
    with pytest.raises(ValueError, match=r"q must have shape \(\.\.\., 2\) for this tree, got \(1,\)"):
        lg.positions(lg.systems.acrobot(), jnp.zeros(1))
