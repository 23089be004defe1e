"""The recursive algorithms (:mod:`lagrange.planar.recursive`: ABA, RNEA, CRBA) against the unrolled
derivation of :mod:`lagrange.dynamics` (chains shorter than ``RECURSIVE_MIN``), the literal
Euler-Lagrange oracle (``benchmarks/oracles/euler_lagrange.py``), finite differences and energy
conservation, and the dispatch on ``lagrange.dynamics.RECURSIVE_MIN``.

Tolerances as in ``tests/lagrange/test_dynamics.py``: M, bias and gravity forces to 1e-12 relative to the
largest entry, accelerations to ``1e-13 cond(M)``. Measured worst cases over these chains:
M/bias/gravity ~1e-15, accelerations ~1e-14 (n <= 12).
"""

import functools
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange import dynamics
from lagrange.planar import recursive
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.lower import lower as planar
from tests.helpers import assert_close  # REL = 1e-12, as the docstring says
from tests.helpers import oracle_terms, rebuilt
from tests.helpers import random_chain as _random_chain
from oracles import euler_lagrange as el


def random_chain(rng, n, cart=False):
    """``tests.helpers.random_chain`` (damping on about half the joints) under a gravity fixed by ``n``."""
    return _random_chain(rng, n, cart=cart, gravity=(9.81, 0.0, 3.7)[n % 3])


def states(rng, chain, k=8):
    n = chain.nv
    q = jnp.asarray(rng.uniform(-np.pi, np.pi, (k, n)))
    qd = jnp.asarray(rng.uniform(-3.0, 3.0, (k, n)))
    u = jnp.asarray(rng.uniform(-2.0, 2.0, (k, chain.m))) if chain.m else None
    return q, qd, u


def _quantities(module, chain, q, qd, u, h=0.05):
    """(M, bias, gravity, qdd, qdd with implicit damping h) for one state."""
    if module is el:  # the oracle has no gravity_forces: the bias at rest (tests.helpers); qdd solved by the caller
        return (*oracle_terms(chain, q, qd), None, None)
    if module is recursive:  # the planar backend's algorithms, on the lowered chain
        chain = planar(chain)
        fd = lambda h: recursive.forward_dynamics(chain, q, qd, u, implicit_damping_dt=h)  # noqa: E731
    else:
        fd = lambda h: dynamics.forward_dynamics(chain, q, qd, u, implicit_damping_dt=h, check=False)  # noqa: E731
    return (module.mass_matrix(chain, q), module.bias_forces(chain, q, qd), module.gravity_forces(chain, q),
            fd(None), fd(h))


def evaluate(module, chain, q, qd, u):
    """:func:`_quantities` one state at a time (vmap), compiled."""
    return jax.jit(jax.vmap(lambda q, qd, u: _quantities(module, chain, q, qd, u)))(q, qd, u)


@pytest.mark.parametrize("n", [2, 3, 5, 8, 12])
def test_agrees_with_unrolled_and_oracle(n):
    rng = np.random.default_rng(100 + n)
    chain = random_chain(rng, n, cart=n % 2 == 0)  # a cart base on even sizes; other prismatic joints at random
    q, qd, u = states(rng, chain, k=4)
    with_unrolled = n < dynamics.RECURSIVE_MIN  # the sizes lagrange.dynamics derives unrolled

    def everything(q, qd, u):
        out = dict(rec=_quantities(recursive, chain, q, qd, u), el=_quantities(el, chain, q, qd, u))
        out["tau_id"] = recursive.inverse_dynamics(planar(chain), q, qd, out["rec"][3])
        out["energy_rec"], out["energy_el"] = recursive.energy(planar(chain), q, qd), el.energy(chain, q, qd)
        if with_unrolled:
            out["unr"] = _quantities(dynamics, chain, q, qd, u)
        return out

    out = jax.jit(jax.vmap(everything))(q, qd, u)
    M, bias, grav, qdd, qdd_h = out["rec"]
    cond = float(np.max(np.linalg.cond(np.asarray(M))))
    # the oracle: dense Hessians of the Lagrangian
    Me, be, ge, _, _ = out["el"]
    assert_close(M, Me, what="M vs oracle")
    assert_close(bias, be, what="bias vs oracle")
    assert_close(grav, ge, what="gravity vs oracle")
    tau = jnp.zeros_like(q) if u is None else u @ dynamics.actuation_matrix(chain).T
    qdde = np.linalg.solve(np.asarray(Me), np.asarray(tau - be)[..., None])[..., 0]  # el.forward_dynamics
    assert_close(qdd, qdde, rel=1e-13 * cond, what="qdd vs oracle")
    # implicit damping: (M + h diag(b)) qdd = B u - bias
    Mh = M if planar(chain).damping is None else M + 0.05 * jnp.diag(planar(chain).damping)
    assert_close(jnp.einsum("kij,kj->ki", Mh, qdd_h), tau - bias, what="implicit damping")
    assert_close(out["tau_id"], tau, rel=1e-13 * cond, what="inverse of forward dynamics")
    for a, b, name in zip(out["energy_rec"], out["energy_el"], ("kinetic", "potential")):
        assert_close(a, b, what=f"{name} energy vs oracle")
    if with_unrolled:
        Mu, bu, gu, qddu, qddu_h = out["unr"]
        assert_close(M, Mu, what="M vs unrolled")
        assert_close(bias, bu, what="bias vs unrolled")
        assert_close(grav, gu, what="gravity vs unrolled")
        assert_close(qdd, qddu, rel=1e-13 * cond, what="qdd vs unrolled")
        assert_close(qdd_h, qddu_h, rel=1e-13 * cond, what="implicit-damping qdd vs unrolled")


@pytest.mark.parametrize("n", [20, 32])
def test_long_chains_satisfy_equations_of_motion(n):
    """For long chains: ABA's qdd solves ``M qdd + bias = B u`` with M from CRBA and the bias from
    RNEA, and CRBA's M equals RNEA's columns ``M e_j = ID(q, 0, e_j) - ID(q, 0, 0)``."""
    rng = np.random.default_rng(n)
    tree = random_chain(rng, n, cart=True)
    q, qd, u = states(rng, tree, k=4)
    chain = planar(tree)
    M, bias, qdd = jax.jit(jax.vmap(lambda q, qd, u: (
        recursive.mass_matrix(chain, q), recursive.bias_forces(chain, q, qd),
        recursive.forward_dynamics(chain, q, qd, u))))(q, qd, u)
    tau = jnp.zeros_like(q) if u is None else u @ dynamics.actuation_matrix(chain).T
    cond = float(np.max(np.linalg.cond(np.asarray(M))))
    assert_close(jnp.einsum("kij,kj->ki", M, qdd), tau - bias, rel=1e-13 * max(1.0, cond ** 0.5),
                 what="M qdd + bias = B u")
    assert_close(qdd, jnp.linalg.solve(M, (tau - bias)[..., None])[..., 0], rel=1e-13 * cond, what="qdd vs solve")
    eye = jnp.eye(n)
    cols = jax.jit(jax.vmap(lambda q: jax.vmap(
        lambda e: recursive.inverse_dynamics(chain, q, 0 * q, e)
                  - recursive.inverse_dynamics(chain, q, 0 * q, 0 * e))(eye)))(q)
    assert_close(M, jnp.swapaxes(cols, -1, -2), what="CRBA vs RNEA columns")
    assert_close(M, jnp.swapaxes(M, -1, -2), rel=0, what="symmetry")


def test_public_api_dispatches_on_threshold():
    """``lagrange.forward_dynamics`` & co. take the recursive path from RECURSIVE_MIN links on,
    with batch dimensions broadcast between q, qd and u."""
    rng = np.random.default_rng(7)
    n = dynamics.RECURSIVE_MIN
    chain = random_chain(rng, n, cart=True)
    jaxpr = str(jax.make_jaxpr(lambda q, qd: lg.forward_dynamics(chain, q, qd))(jnp.zeros(n), jnp.zeros(n)))
    assert "scan" in jaxpr
    short = random_chain(rng, n - 1)
    jaxpr = str(jax.make_jaxpr(lambda q, qd: lg.forward_dynamics(short, q, qd))(jnp.zeros(n - 1), jnp.zeros(n - 1)))
    assert "scan" not in jaxpr
    # batch dimensions broadcast: q (2, 3, n), qd (n,), u (3, m)
    q = jnp.asarray(rng.uniform(-2, 2, (2, 3, n)))
    qd = jnp.asarray(rng.uniform(-2, 2, (n,)))
    u = jnp.asarray(rng.uniform(-2, 2, (3, chain.m))) if chain.m else None

    def quantities(q, u):
        return dict(qdd=lg.forward_dynamics(chain, q, qd, u), M=lg.mass_matrix(chain, q),
                    bias=lg.bias_forces(chain, q, qd), gravity=lg.gravity_forces(chain, q))

    out = jax.jit(quantities)(q, u)  # batched arguments, broadcast inside
    ub = None if u is None else jnp.broadcast_to(u, (2,) + u.shape)
    each = jax.jit(jax.vmap(jax.vmap(quantities)))(q, ub)  # one state at a time
    for key in out:
        assert_close(out[key], each[key], rel=1e-14, what=f"{key} batch")
    assert out["qdd"].shape == (2, 3, n) and out["M"].shape == (2, 3, n, n)
    with pytest.raises(ValueError, match="u must have shape"):
        lg.forward_dynamics(chain, q, qd, jnp.zeros((3, chain.m + 1)))


def _with_mass(chain, mass):
    return rebuilt(chain, mass=mass)


def test_gradients_match_unrolled_and_finite_differences():
    """Reverse-mode gradients of a scalar of qdd w.r.t. q, qd and the link masses: equal to the
    unrolled path's (n = 4) and to central finite differences along random directions
    (n = 4 and n = 10; step 1e-5, truncation error ~1e-10 relative)."""
    rng = np.random.default_rng(3)
    for n in (4, 10):
        chain = random_chain(rng, n, cart=True)
        q, qd, u = (x[0] if x is not None else None for x in states(rng, chain, k=1))
        w = jnp.asarray(rng.normal(size=n))

        def loss(fd, q, qd, mass):
            return jnp.sum(w * jnp.tanh(fd(_with_mass(chain, mass), q, qd, u)))

        rec = jax.jit(functools.partial(loss, lambda c, q, qd, u: recursive.forward_dynamics(planar(c), q, qd, u)))
        args = (q, qd, chain.mass)
        g = jax.jit(jax.grad(rec, argnums=(0, 1, 2)))(*args)
        if n == 4:  # lg.forward_dynamics derives a 4-link chain unrolled
            gu = jax.jit(jax.grad(functools.partial(loss, lg.forward_dynamics), argnums=(0, 1, 2)))(*args)
            for a, b, name in zip(g, gu, ("q", "qd", "mass")):
                assert_close(a, b, rel=1e-11, what=f"grad wrt {name} vs unrolled")
        eps = 1e-5
        for _ in range(3):
            d = tuple(jnp.asarray(rng.normal(size=n)) for _ in range(3))
            plus = rec(*(a + eps * v for a, v in zip(args, d)))
            minus = rec(*(a - eps * v for a, v in zip(args, d)))
            fd = float(plus - minus) / (2 * eps)
            ad = float(sum(jnp.dot(gi, v) for gi, v in zip(g, d)))
            assert abs(fd - ad) <= 1e-7 * max(1.0, abs(ad)), (n, fd, ad)


def test_energy_conserved_20_link_pendulum():
    """A 20-link pendulum released from a bent pose, no damping, Dopri8 at h = 2 ms for 0.5 s:
    the total energy (from RNEA's kinematics) stays within 1e-7 of its potential-energy scale
    (measured 3e-10)."""
    n = 20
    chain = lg.systems.n_link_pendulum(n, mass=0.5, length=0.25)
    q0 = jnp.asarray(0.3 * np.sin(np.arange(n)))
    traj = jax.jit(lambda q0: lg.simulate(chain, q0, jnp.zeros(n), None, 0.01, lg.Dopri8(), substeps=5, steps=50))(q0)

    E = jax.jit(jax.vmap(lambda q, qd: sum(lg.energy(chain, q, qd))))(traj.q, traj.qd)  # compiled: 5x faster than eager
    scale = float(jnp.sum(chain.mass) * planar(chain).gravity * jnp.sum(planar(chain).length))
    moved = float(jnp.max(jnp.abs(traj.q[-1] - q0)))
    assert moved > 0.1  # it did swing
    err = float(jnp.max(jnp.abs(E - E[0])))
    print(f"20-link pendulum: energy error {err:.3g} J, scale {scale:.3g} J")
    assert err <= 1e-7 * scale, f"energy error {err:.3g} J vs scale {scale:.3g} J"


def test_compiled_program_does_not_grow_with_n():
    """The traced program of forward dynamics and of its gradient has the same number of
    equations for n = 16 and n = 32 (scans over links, nothing unrolled), and n = 32 compiles
    quickly (printed; measured ~0.7-1 s CPU for the forward dynamics)."""

    def programs(n):
        chain = lg.systems.n_link_pendulum(n, gear=1.0, damping=0.1)
        z = jnp.zeros(n)
        fwd = lambda q, qd, u: lg.forward_dynamics(chain, q, qd, u)  # noqa: E731
        grad = jax.grad(lambda q, qd, u: jnp.sum(fwd(q, qd, u) ** 2), argnums=(0, 1, 2))
        return fwd, grad, (z, z, z)

    sizes = {}
    for n in (16, 32):
        fwd, grad, args = programs(n)
        sizes[n] = tuple(len(jax.make_jaxpr(f)(*args).jaxpr.eqns) for f in (fwd, grad))
    assert sizes[16] == sizes[32], sizes
    fwd, grad, args = programs(32)
    t, c = time.perf_counter(), time.process_time()
    jax.jit(fwd).lower(*args).compile()
    print(f"n = 32 forward compile: {time.perf_counter() - t:.2f} s wall, {time.process_time() - c:.2f} s CPU")


@pytest.mark.parametrize("n", [32, 64])
def test_link_angles_sines_by_angle_addition_stay_exact(n):
    """The kinematics scan forms the link angles' sines and cosines by the angle-addition formulas from the joint
    angles': their rounding adds up over the links. Against the exact sines of the summed angles (long double)
    the error stays under 20 float64 ulps at 1 (measured 1.3e-15 at n = 32, 1.9e-15 at n = 64)."""
    chain = planar(lg.systems.n_link_pendulum(n))  # the lowered chain: its parameters NumPy arrays
    q = np.random.default_rng(0).uniform(-3, 3, (n, 4096))
    k = LinkKinematics(chain, jnp.asarray(q), None, 1)
    phi = np.cumsum(q.astype(np.longdouble), axis=0)
    tol = 20 * np.finfo(np.float64).eps
    assert float(np.max(np.abs(np.asarray(k.sin) - np.sin(phi)))) <= tol
    assert float(np.max(np.abs(np.asarray(k.cos) - np.cos(phi)))) <= tol
