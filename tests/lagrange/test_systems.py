"""The catalogue (lagrange/systems.py): every system's defaults against the CE-APG paper's constants and the
structure the module's table documents (coordinates, actuated joints, gears, thin-rod inertias), ``BRAX_V1`` against
the authors' Brax v1 configs, and the centre-of-mass and inertia keywords (and the Brax v1 bodies built from them)
against the hand-written closed forms of ``benchmarks/oracles/closed_form.py``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.planar.lower import lower as planar
from tests.helpers import assert_close, per_state, states
from oracles import closed_form as cf


def _com_inertia_cases(rng):
    """The cart and acrobot chains built with every ``com``/``inertia`` keyword: the authors' Brax v1 bodies
    (``lagrange.systems.BRAX_V1``) and random values, with the closed-form parameters they stand for."""
    U = rng.uniform
    b1 = lg.systems.BRAX_V1
    a, c, d = b1["acrobot"], b1["cartpole"], b1["double_cartpole"]
    yield "cartpole", lg.systems.cartpole(**c), cf.cartpole, cf.CartpoleParams(
        c["cart_mass"], c["pole_mass"], c["pole_length"], c["pole_com"], c["pole_inertia"])
    yield "acrobot", lg.systems.acrobot(**a), cf.acrobot, cf.AcrobotParams(
        *a["masses"], *a["lengths"], *a["coms"], *a["inertias"])
    yield "double_cartpole", lg.systems.double_cartpole(**d), cf.double_cartpole, cf.DoubleCartpoleParams(
        d["cart_mass"], *d["pole_masses"], *d["pole_lengths"], *d["pole_coms"], *d["pole_inertias"])
    l, lc, i = U(0.3, 2), U(0.05, 1), U(0.01, 2)
    yield "cartpole", lg.systems.cartpole(pole_length=l, pole_com=lc, pole_inertia=i), cf.cartpole, \
        cf.CartpoleParams(pole_length=l, pole_com=lc, pole_inertia=i)
    (l1, l2), (c1, c2), (i1, i2) = U(0.3, 2, 2), U(0.05, 1, 2), U(0.01, 2, 2)
    yield "acrobot", lg.systems.acrobot(lengths=(l1, l2), coms=(c1, c2), inertias=(i1, i2)), cf.acrobot, \
        cf.AcrobotParams(l1=l1, l2=l2, lc1=c1, lc2=c2, I1=i1, I2=i2)
    yield "double_cartpole", lg.systems.double_cartpole(pole_lengths=(l1, l2), pole_coms=(c1, c2),
                                                        pole_inertias=(i1, i2)), cf.double_cartpole, \
        cf.DoubleCartpoleParams(l1=l1, l2=l2, lc1=c1, lc2=c2, I1=i1, I2=i2)


def test_com_and_inertia_keywords_match_closed_forms():
    """The centre-of-mass and inertia keywords of the catalogue (and the Brax v1 presets built from them) give the
    hand-written equations with those parameters, to 1e-12."""
    rng = np.random.default_rng(2)
    cases = list(_com_inertia_cases(rng))
    preset = planar(cases[1][1])
    assert np.allclose(preset.inertia, 1.0) and np.allclose(preset.com, 0.45)  # the presets are not the rods
    for name, chain, ref, p in cases:
        q, qd = states(rng, chain.nv)
        u = jnp.asarray(rng.uniform(-1, 1, (q.shape[0], 1)))
        got = per_state(lambda ch, q, qd, u: (lg.mass_matrix(ch, q), lg.bias_forces(ch, q, qd),
                                              lg.forward_dynamics(ch, q, qd, u)), chain, q, qd, u)
        want = jax.jit(lambda q, qd, u: (ref.mass_matrix(p, q), ref.bias(p, q, qd),
                                         ref.forward_dynamics(p, q, qd, u)))(q, qd, u)
        assert_close(got[0], want[0], what=f"{name} M")
        assert_close(got[1], want[1], what=f"{name} bias")
        cond = float(np.max(np.linalg.cond(np.asarray(got[0]))))
        assert_close(got[2], want[2], rel=1e-13 * max(cond, 10.0), what=f"{name} qdd")


def _rod(mass, length):
    """A thin rod's moment of inertia about its centre [kg m^2]."""
    return mass * length**2 / 12


def test_defaults_are_the_papers_constants():
    """The CE-APG paper's bodies as the module docstring lists them: cart 10.47 kg, poles 5.02 kg and 1 m, acrobot
    links 2.5 kg and 1 m; gears 1 (pendulum), 100 (cartpole), 1000 (double cartpole) and 25 (acrobot's elbow); links
    are thin rods (com at l/2, inertia m l^2 / 12) and the cart a point mass; gravity 9.81 m/s^2, no damping."""
    want = {  # joints, masses, lengths, actuated joints, gears
        "pendulum": (("revolute",), (1.0,), (1.0,), (0,), (1.0,)),
        "cartpole": (("prismatic", "revolute"), (10.47, 5.02), (0.0, 1.0), (0,), (100.0,)),
        "double_cartpole": (("prismatic", "revolute", "revolute"), (10.47, 5.02, 5.02), (0.0, 1.0, 1.0), (0,),
                            (1000.0,)),
        "acrobot": (("revolute", "revolute"), (2.5, 2.5), (1.0, 1.0), (1,), (25.0,)),
    }
    for name, (joints, mass, length, actuated, gear) in want.items():
        c = planar(getattr(lg.systems, name)())  # the planar backend's reading: the links' parameters
        assert (c.joints, c.actuated, c.n, c.m) == (joints, actuated, len(joints), 1), name
        np.testing.assert_array_equal(c.mass, mass)
        np.testing.assert_array_equal(c.length, length)
        np.testing.assert_array_equal(c.gear, gear)
        np.testing.assert_array_equal(c.com, [l / 2 for l in length])
        np.testing.assert_allclose(c.inertia, [_rod(m, l) for m, l in zip(mass, length)], rtol=1e-15, atol=0)
        assert float(c.gravity) == 9.81 and c.damping is None and c.armature is None
        assert all(a == 0.0 for a in c.axes)  # carts slide along x


def test_n_link_pendulum():
    """``n`` identical 1 kg, 1 m rods; passive unless ``gear`` is given, then every joint actuated; ``n`` checked."""
    c = planar(lg.systems.n_link_pendulum(4))
    assert (c.n, c.m, c.actuated, c.joints) == (4, 0, (), ("revolute",) * 4)
    np.testing.assert_array_equal(c.mass, [1.0] * 4) and np.testing.assert_array_equal(c.length, [1.0] * 4)
    np.testing.assert_allclose(c.inertia, [_rod(1.0, 1.0)] * 4, rtol=1e-15)
    g = planar(lg.systems.n_link_pendulum(3, mass=0.5, length=0.25, gear=2.0, damping=0.1, gravity=3.7))
    assert (g.m, g.actuated) == (3, (0, 1, 2)) and float(g.gravity) == 3.7
    np.testing.assert_array_equal(g.gear, [2.0] * 3) and np.testing.assert_array_equal(g.damping, [0.1] * 3)
    np.testing.assert_allclose(g.inertia, [_rod(0.5, 0.25)] * 3, rtol=1e-15)
    for bad in (0, -2, 1.5, True, "3"):
        with pytest.raises(ValueError, match=r"n must be an integer >= 1"):
            lg.systems.n_link_pendulum(bad)


def test_brax_v1_is_the_authors_bodies():
    """``BRAX_V1`` holds the authors' Brax v1 configs as the docstring describes them: acrobot capsules 1 m long
    hinged 0.45 m either side of the centre (so 0.9 m hinge to hinge, com 0.45 m), cart poles hinged 0.3 m from their
    centre and drawn 0.6 m long, masses 2.5 kg (acrobot) and 10.471975 / 5.0185914 kg (cart / poles), and Brax v1's
    inertia of 1 kg m^2 on every link; the constructors build exactly those chains, with the paper's gears."""
    b = lg.systems.BRAX_V1
    assert set(b) == {"acrobot", "cartpole", "double_cartpole"}
    a = planar(lg.systems.acrobot(**b["acrobot"]))
    np.testing.assert_array_equal(a.mass, [2.5, 2.5]) and np.testing.assert_array_equal(a.length, [0.9, 0.9])
    np.testing.assert_array_equal(a.com, [0.45, 0.45]) and np.testing.assert_array_equal(a.inertia, [1.0, 1.0])
    np.testing.assert_array_equal(a.gear, [25.0])
    c = planar(lg.systems.cartpole(**b["cartpole"]))
    np.testing.assert_array_equal(c.mass, [10.471975, 5.0185914]) and np.testing.assert_array_equal(c.gear, [100.0])
    np.testing.assert_array_equal(c.length, [0.0, 0.6]) and np.testing.assert_array_equal(c.com, [0.0, 0.3])
    np.testing.assert_array_equal(c.inertia, [0.0, 1.0])
    d = planar(lg.systems.double_cartpole(**b["double_cartpole"]))
    np.testing.assert_array_equal(d.mass, [10.471975, 5.0185914, 5.0185914])
    np.testing.assert_array_equal(d.length, [0.0, 0.6, 0.6]) and np.testing.assert_array_equal(d.com, [0.0, 0.3, 0.3])
    np.testing.assert_array_equal(d.inertia, [0.0, 1.0, 1.0]) and np.testing.assert_array_equal(d.gear, [1000.0])
    # the docstring's comparison: Brax v1's 1 kg m^2 against a 1 m rod of the same mass
    assert 4.5 < 1.0 / _rod(2.5, 1.0) < 5.0 and 2.3 < 1.0 / _rod(5.02, 1.0) < 2.5


def test_every_parameter_is_a_keyword():
    """Each keyword reaches its field (a parameter the catalogue dropped would leave the default)."""
    p = planar(lg.systems.pendulum(mass=2.0, length=0.5, com=0.1, inertia=0.3, damping=0.2, gear=None, gravity=1.6))
    assert (p.m, float(p.gravity)) == (0, 1.6)
    np.testing.assert_array_equal([p.mass[0], p.length[0], p.com[0], p.inertia[0], p.damping[0]],
                                  [2.0, 0.5, 0.1, 0.3, 0.2])
    c = planar(lg.systems.cartpole(cart_mass=3.0, pole_mass=0.7, pole_length=2.0, damping=0.4, gear=7.0,
                                   gravity=1.0))
    np.testing.assert_array_equal(c.mass, [3.0, 0.7]) and np.testing.assert_array_equal(c.length, [0.0, 2.0])
    np.testing.assert_array_equal(c.damping, [0.4, 0.0]) and np.testing.assert_array_equal(c.gear, [7.0])
    np.testing.assert_allclose(c.inertia, [0.0, _rod(0.7, 2.0)], rtol=1e-15)
    a = planar(lg.systems.acrobot(masses=(1.0, 2.0), lengths=(0.5, 1.5), damping=0.3, gear=4.0))
    np.testing.assert_array_equal(a.mass, [1.0, 2.0]) and np.testing.assert_array_equal(a.com, [0.25, 0.75])
    np.testing.assert_array_equal(a.damping, [0.3, 0.3]) and np.testing.assert_array_equal(a.gear, [4.0])
    d = planar(lg.systems.double_cartpole(cart_mass=2.0, pole_masses=(0.5, 0.25), pole_lengths=(0.4, 0.8),
                                          damping=0.1))
    np.testing.assert_array_equal(d.mass, [2.0, 0.5, 0.25]) and np.testing.assert_array_equal(d.com, [0.0, 0.2, 0.4])
    np.testing.assert_array_equal(d.damping, [0.1, 0.0, 0.0])
