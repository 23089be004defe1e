"""The equations of motion against independent references.

References: the hand-written closed forms of ``benchmarks/oracles/closed_form.py`` (pendulum, cartpole,
acrobot, double cartpole), the literal Euler-Lagrange derivation of
``benchmarks/oracles/euler_lagrange.py`` (dense Hessians of L = T - V, ``jnp.linalg.solve``) for random
chains, the Christoffel symbols of ``M`` (so ``C qd`` is tied to ``M``), and central finite
differences (``jax.test_util.check_grads``).

Tolerances. All in float64 (``tests/conftest.py``), unit round-off ``u = 1.1e-16``. A quantity
computed by a few tens of floating-point operations from O(1) inputs has a rounding error of a
few tens of ``u`` relative to its magnitude (measured worst case: 2.5e-15), so M, bias and gravity are
compared to ``1e-12`` relative to the largest entry (the issue's bar), a margin of ~400x
over the measured worst case. Accelerations come out of a linear solve and lose a further
factor ``cond(M)``; they are compared to ``1e-13 cond(M)`` relative.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.planar.lower import lower as planar
from tests.helpers import REL, assert_close, oracle_terms, per_state, random_chain, rebuilt, states
from oracles import closed_form as cf
from oracles import euler_lagrange as el


# ------------------------------------------------------------------ closed forms


def _closed_form_cases(rng):
    """(name, lagrange chain, closed-form module, params) with random physical parameters."""
    U = rng.uniform
    m, l, c, i, b, g = U(0.5, 3), U(0.3, 2), U(0.1, 1), U(0.01, 0.5), U(0.1, 1), U(1, 20)
    yield "pendulum", lg.systems.pendulum(
        mass=m, length=l, com=c, inertia=i, damping=b, gear=2.0, gravity=g
    ), cf.pendulum, cf.PendulumParams(m, l, c, i, b, 2.0, g)
    mc, mp, l, b = U(1, 12), U(0.5, 6), U(0.3, 2), U(0.1, 1)
    yield "cartpole", lg.systems.cartpole(
        cart_mass=mc, pole_mass=mp, pole_length=l, damping=b, gear=50.0, gravity=g
    ), cf.cartpole, cf.CartpoleParams(mc, mp, l, l / 2, mp * l**2 / 12, b, 50.0, g)
    m1, m2, l1, l2, I1, I2, b = U(0.5, 3), U(0.5, 3), U(0.3, 2), U(0.3, 2), U(0.01, 0.5), U(0.01, 0.5), U(0.1, 1)
    yield "acrobot", lg.systems.acrobot(
        masses=(m1, m2), lengths=(l1, l2), inertias=(I1, I2), damping=b, gear=7.0, gravity=g
    ), cf.acrobot, cf.AcrobotParams(m1, m2, l1, l2, l1 / 2, l2 / 2, I1, I2, b, 7.0, g)
    mc, m1, m2, l1, l2, b = U(1, 12), U(0.5, 6), U(0.5, 6), U(0.3, 2), U(0.3, 2), U(0.1, 1)
    yield "double_cartpole", lg.systems.double_cartpole(
        cart_mass=mc, pole_masses=(m1, m2), pole_lengths=(l1, l2), damping=b, gear=300.0, gravity=g
    ), cf.double_cartpole, cf.DoubleCartpoleParams(
        mc, m1, m2, l1, l2, l1 / 2, l2 / 2, m1 * l1**2 / 12, m2 * l2**2 / 12, b, 300.0, g
    )


def _default_cases():
    for name, mod in cf.SYSTEMS.items():
        yield name, getattr(lg.systems, name)(), mod, mod.Params()


@pytest.mark.parametrize("which", ["defaults", "random"])
def test_closed_forms(which):
    """M, bias (C qd + T + damping qd), T and qdd equal the hand-written equations to 1e-12."""
    rng = np.random.default_rng(1)
    cases = list(_default_cases() if which == "defaults" else _closed_form_cases(rng))
    assert [c[0] for c in cases] == ["pendulum", "cartpole", "acrobot", "double_cartpole"]
    for name, chain, ref, p in cases:
        q, qd = states(rng, chain.nv)
        u = jnp.asarray(rng.uniform(-1, 1, (q.shape[0], 1)))
        got = jax.jit(
            jax.vmap(
                lambda q, qd, u: (
                    lg.mass_matrix(chain, q),
                    lg.bias_forces(chain, q, qd),
                    lg.gravity_forces(chain, q),
                    lg.forward_dynamics(chain, q, qd, u),
                )
            )
        )(q, qd, u)
        want = jax.jit(
            lambda q, qd, u: (
                ref.mass_matrix(p, q), ref.bias(p, q, qd), ref.gravity(p, q), ref.forward_dynamics(p, q, qd, u)
            )
        )(q, qd, u)
        for what, a, b in zip(("M", "bias", "gravity"), got, want):
            assert_close(a, b, what=f"{name} {what}")
        cond = float(np.max(np.linalg.cond(np.asarray(got[0]))))
        assert_close(got[3], want[3], rel=1e-13 * max(cond, 10.0), what=f"{name} qdd")


def test_closed_forms_are_not_trivially_equal():
    """A wrong parameter (pole length 1.0 vs 1.1) is far outside the tolerance: the check can fail."""
    rng = np.random.default_rng(2)
    q, qd = states(rng, 2)
    chain = lg.systems.cartpole(pole_length=1.1)
    err = np.max(np.abs(per_state(lg.bias_forces, chain, q, qd) - cf.cartpole.bias(cf.CartpoleParams(), q, qd)))
    assert err > 1e-3


# ------------------------------------------------------------------ random chains vs Euler-Lagrange


SIZES = (1, 2, 3, 4, 7)  # 1-4 links take the relative-angle path, 7 the recursive one (lagrange.planar.recursive)


@functools.cache
def chain_results(n):
    """Everything the random-chain tests compare, computed in one compiled call per chain size."""
    for seed in range(100 * n, 100 * n + 100):  # the first seed giving a mix of joint kinds
        rng = np.random.default_rng(seed)
        chain = random_chain(rng, n)
        revolute = planar(chain).joints.count("revolute")
        if n < 3 or (revolute >= n / 2 and revolute < n):
            break
    q, qd = states(rng, n, k=4)
    u = jnp.asarray(rng.uniform(-1, 1, (4, chain.m)))

    @jax.jit
    def run(q, qd, u):
        def one(q, qd, u):
            uu = u if chain.m else None
            M = lg.mass_matrix(chain, q)
            qdd = lg.forward_dynamics(chain, q, qd, uu)
            dM = jax.jacfwd(lambda x: lg.mass_matrix(chain, x))(q)  # dM[i, j, k] = dM_ij / dq_k
            # Christoffel form of the velocity-product forces:
            # C_ij = sum_k 1/2 (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) qd_k
            C = 0.5 * (
                jnp.einsum("ijk,k->ij", dM, qd) + jnp.einsum("ikj,k->ij", dM, qd) - jnp.einsum("jki,k->ij", dM, qd)
            )
            el_M, el_bias, el_gravity = oracle_terms(chain, q, qd)
            return dict(
                M=M,
                bias=lg.bias_forces(chain, q, qd),
                gravity=lg.gravity_forces(chain, q),
                qdd=qdd,
                tau=lg.inverse_dynamics(chain, q, qd, qdd),
                kinetic=lg.energy(chain, q, qd)[0],
                dV=jax.grad(lambda x: lg.energy(chain, x, qd)[1])(q),
                C=C,
                Mdot=jax.jvp(lambda x: lg.mass_matrix(chain, x), (q,), (qd,))[1],
                el_M=el_M,
                el_bias=el_bias,
                el_gravity=el_gravity,
                el_qdd=el.accelerations(chain, el_M, el_bias, uu),
            )

        return jax.vmap(one)(q, qd, u)

    out = {k: np.asarray(v) for k, v in run(q, qd, u).items()}
    return chain, np.asarray(q), np.asarray(qd), np.asarray(u), out


@pytest.mark.parametrize("n", SIZES)
def test_random_chain_matches_euler_lagrange(n):
    chain, q, qd, u, r = chain_results(n)
    assert_close(r["M"], r["el_M"], what="M")
    assert_close(r["bias"], r["el_bias"], what="bias")
    assert_close(r["gravity"], r["el_gravity"], what="gravity")
    cond = float(np.max(np.linalg.cond(r["M"])))
    assert_close(r["qdd"], r["el_qdd"], rel=1e-13 * max(cond, 10.0), what="qdd")


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_frame_offsets_and_off_line_coms_match_euler_lagrange(n):
    """Link frames turned against their parents (``offset``) and centres of mass off the link line (``com_normal``),
    on both derivations (unit vectors below ``RECURSIVE_MIN`` links, the recursive algorithms at any size), against
    the literal derivation, whose forward kinematics writes both in directly."""
    from lagrange import dynamics
    from lagrange.planar import recursive

    rng = np.random.default_rng(70 + n)
    chain = random_chain(rng, n, frames=True)
    assert planar(chain).com_normal is not None and any(o != 0.0 for o in planar(chain).offsets)
    q, qd = states(rng, n, k=4)
    # the recursive algorithms on the lowered chain at any size; the public functions (the unrolled derivation here)
    modules = [(recursive, planar(chain))] + ([(dynamics, chain)] if n < dynamics.RECURSIVE_MIN else [])

    @jax.jit
    @jax.vmap
    def run(q, qd):
        el_M, el_bias, el_gravity = oracle_terms(chain, q, qd)
        out = {"el": (el_M, el_bias, el_gravity, sum(el.energy(chain, q, qd)), el.com_and_angles(chain, q)[0])}
        for mod, c in modules:
            out[mod.__name__] = (mod.mass_matrix(c, q), mod.bias_forces(c, q, qd), mod.gravity_forces(c, q),
                                 sum(mod.energy(c, q, qd)), lg.com_positions(chain, q)[..., ::2])
        return out

    out = run(q, qd)
    for mod, _ in modules:
        for name, a, b in zip(("M", "bias", "gravity", "energy", "com"), out[mod.__name__], out["el"]):
            assert_close(a, b, what=f"{name} ({mod.__name__})")


def test_control_range_clamps_before_the_gear():
    """A control range clamps ``u`` as MuJoCo clamps a limited ``ctrl``: outside it the control has no effect."""
    links = [Link("prismatic", 1.0, gear=2.0, control_range=(-1.0, 0.5)), Link("revolute", 0.5, 1.0, gear=3.0)]
    chain = Chain(links)
    free = Chain([Link("prismatic", 1.0, gear=2.0), Link("revolute", 0.5, 1.0, gear=3.0)])
    q, qd = jnp.array([0.1, 0.4]), jnp.array([0.3, -0.2])
    for u, clamped in (([3.0, 7.0], [0.5, 7.0]), ([-4.0, -1.0], [-1.0, -1.0]), ([0.2, 1.0], [0.2, 1.0])):
        assert_close(lg.forward_dynamics(chain, q, qd, jnp.array(u)),
                     lg.forward_dynamics(free, q, qd, jnp.array(clamped)))
    assert planar(chain).control_ranges == ((-1.0, 0.5), None) and free.control_ranges is None
    with pytest.raises(ValueError, match="control_range"):
        Link("revolute", 1.0, 1.0, control_range=(-1.0, 1.0))  # not actuated
    with pytest.raises(ValueError, match="control_range"):
        Link("revolute", 1.0, 1.0, gear=1.0, control_range=(1.0, -1.0))


def test_random_chains_cover_every_feature():
    """The random chains above exercise every optional term, so the comparison means something."""
    chains = [planar(chain_results(n)[0]) for n in SIZES]
    assert any("prismatic" in c.joints for c in chains)
    assert any(a != 0.0 for c in chains for a in c.axes)
    assert any(c.damping is not None for c in chains) and any(c.damping is None for c in chains)
    assert any(c.armature is not None for c in chains)
    assert any(c.m > 0 for c in chains) and any(c.gravity is None for c in chains)
    assert any(c.gravity is not None and float(c.gravity) != 9.81 for c in chains)


@pytest.mark.parametrize("n", SIZES)
def test_mass_matrix_spd_and_christoffel(n):
    """M = M^T > 0; C qd = bias - T - damping qd equals the Christoffel form built from dM/dq (this
    ties the velocity terms to M), and Mdot - 2C is skew-symmetric."""
    chain, q, qd, u, r = chain_results(n)
    M = r["M"]
    # Built from one lower triangle, but XLA may duplicate and re-fuse a shared entry: a few ulps.
    assert_close(M, np.swapaxes(M, -1, -2), rel=4e-16)
    assert np.all(np.linalg.eigvalsh(M)[:, 0] > 0)
    damping = 0.0 if planar(chain).damping is None else np.asarray(planar(chain).damping) * qd
    Cqd = r["bias"] - r["gravity"] - damping
    assert_close(Cqd, np.einsum("bij,bj->bi", r["C"], qd))
    S = r["Mdot"] - 2 * r["C"]
    assert_close(S + np.swapaxes(S, -1, -2), np.zeros_like(S), rel=REL * max(1.0, float(np.max(np.abs(r["Mdot"])))))


@pytest.mark.parametrize("n", SIZES)
def test_inverse_of_forward_dynamics(n):
    """inverse_dynamics(q, qd, forward_dynamics(q, qd, u)) == B u (damping and gravity included)."""
    chain, q, qd, u, r = chain_results(n)
    B = np.asarray(lg.actuation_matrix(chain))
    assert B.shape == (n, chain.m)
    # the residual of a backward-stable solve is ~u |M| |qdd|, not amplified by cond(M)
    scale = float(np.max(np.abs(r["M"]))) * float(np.max(np.abs(r["qdd"])))
    assert_close(r["tau"], u @ B.T, rel=REL * max(1.0, scale))


@pytest.mark.parametrize("n", SIZES)
def test_energy_matches_mass_matrix(n):
    """kinetic = 1/2 qd^T M qd, and the gradient of the potential is T."""
    chain, q, qd, u, r = chain_results(n)
    assert_close(r["kinetic"], 0.5 * np.einsum("bi,bij,bj->b", qd, r["M"], qd))
    assert_close(r["dV"], r["gravity"])


def test_actuation_matrix_places_gears():
    chain = Chain([Link("revolute", 1.0, 1.0, gear=3.0), Link("revolute", 1.0, 1.0), Link("prismatic", 1.0, gear=2.5)])
    np.testing.assert_array_equal(lg.actuation_matrix(chain), [[3.0, 0.0], [0.0, 0.0], [0.0, 2.5]])


@pytest.mark.parametrize("name", ["pendulum", "cartpole", "acrobot", "double_cartpole"])
def test_batch_dims(name):
    """Leading batch dimensions (3, 4, n) give the same numbers as one state at a time."""
    chain = getattr(lg.systems, name)(damping=0.3)
    n, m = chain.nv, chain.m
    rng = np.random.default_rng(3)
    q = jnp.asarray(rng.uniform(-3, 3, (3, 4, n)))
    qd = jnp.asarray(rng.uniform(-3, 3, (3, 4, n)))
    u = jnp.asarray(rng.uniform(-1, 1, (3, 4, m)))

    def quantities(q, qd, u):
        qdd = lg.forward_dynamics(chain, q, qd, u)
        kin, pot = lg.energy(chain, q, qd)
        return dict(
            M=lg.mass_matrix(chain, q),
            bias=lg.bias_forces(chain, q, qd),
            gravity=lg.gravity_forces(chain, q),
            qdd=qdd,
            tau=lg.inverse_dynamics(chain, q, qd, qdd),
            kin=kin,
            pot=pot,
        )

    batched = jax.jit(quantities)(q, qd, u)
    single = jax.jit(jax.vmap(jax.vmap(quantities)))(q, qd, u)
    for key in single:
        assert batched[key].shape == single[key].shape, key
        # same arithmetic, possibly fused differently by XLA: round-off only
        assert_close(batched[key], single[key], rel=1e-13)


# ------------------------------------------------------------------ gradients w.r.t. parameters


def test_parameter_gradients_finite_differences():
    """d qdd / d(mass, length, inertia, damping, gravity) against central differences
    (jax.test_util.check_grads: step 1e-4, truncation ~1e-8 and round-off ~1e-12 relative, so its
    float64 tolerance 1e-5 is met with a wide margin), in forward and reverse mode."""
    rng = np.random.default_rng(5)
    chain = random_chain(rng, 3, damped=1.0)
    assert planar(chain).damping is not None and planar(chain).gravity is not None
    q, qd = (x[0] for x in states(rng, 3, k=1))
    u = jnp.ones(chain.m)

    def f(mass, length, inertia, damping, gravity):
        c = rebuilt(chain, mass=mass, length=length, inertia=inertia, damping=damping, gravity=gravity)
        return lg.forward_dynamics(c, q, qd, u if c.m else None)

    args = (chain.mass, planar(chain).length, planar(chain).inertia, planar(chain).damping, planar(chain).gravity)
    check_grads(jax.jit(f), args, order=1, modes=("fwd", "rev"))


def test_parameter_gradients_match_closed_form():
    """d qdd / d(m1, m2, I1, I2, gravity) of the acrobot equals autodiff of the closed form."""
    rng = np.random.default_rng(6)
    chain = lg.systems.acrobot()
    p = cf.AcrobotParams()
    q, qd = (x[0] for x in states(rng, 2, k=1))
    u = jnp.array([0.3])

    def f_lg(mass, inertia, g):
        return lg.forward_dynamics(rebuilt(chain, mass=mass, inertia=inertia, gravity=g), q, qd, u)

    def f_cf(mass, inertia, g):
        pp = p._replace(m1=mass[0], m2=mass[1], I1=inertia[0], I2=inertia[1], gravity=g)
        return cf.acrobot.forward_dynamics(pp, q, qd, u)

    args = (chain.mass, planar(chain).inertia, planar(chain).gravity)
    for a, b in zip(jax.jacrev(f_lg, argnums=(0, 1, 2))(*args), jax.jacrev(f_cf, argnums=(0, 1, 2))(*args)):
        assert_close(a, b, rel=1e-10)
