"""Forward kinematics (lagrange/kinematics.py): ``positions``, ``tip_positions`` and ``com_positions`` of planar
chains against trigonometry written by hand (q = 0 hangs down; a link at absolute angle phi points along
(sin phi, -cos phi); a cart slides along x, or along its axis turned by the angle before it; every row ``(x, 0, z)``
in the world's x-z plane), their batch shapes, and the planar backend's frame jets (lagrange/planar/frames.py)
against ``jax.jvp`` of the positions. Joint origins against MuJoCo's ``xpos`` are in test_against_mujoco.py.

Tolerance: a handful of float64 operations on O(1) numbers, so 1e-14 absolute (measured ~1e-16).
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.kinematics import tip_positions
from lagrange.planar.frames import frames
from lagrange.planar.lower import lower as planar

ATOL = 1e-14


def _d(phi):
    return np.array([math.sin(phi), -math.cos(phi)])


def _in_plane(rows):
    """``(x, z)`` rows as the world's ``(x, 0, z)``."""
    rows = np.asarray(rows)
    return np.stack([rows[..., 0], np.zeros(rows.shape[:-1]), rows[..., 1]], axis=-1)


def test_two_link_chain_by_hand():
    """A double pendulum with uneven links and off-centre masses, at random q."""
    l1, l2, c1, c2 = 0.8, 1.3, 0.3, 0.9
    chain = Chain([Link("revolute", 1.0, l1, com=c1), Link("revolute", 2.0, l2, com=c2, gear=1.0)])
    rng = np.random.default_rng(0)
    for q1, q2 in rng.uniform(-2 * np.pi, 2 * np.pi, (20, 2)):
        elbow = l1 * _d(q1)
        tip = elbow + l2 * _d(q1 + q2)
        want = np.stack([np.zeros(2), elbow, tip])
        want_com = np.stack([c1 * _d(q1), elbow + c2 * _d(q1 + q2)])
        q = jnp.array([q1, q2])
        np.testing.assert_allclose(lg.positions(chain, q), _in_plane(want[:2]), rtol=0, atol=ATOL)  # the joints
        np.testing.assert_allclose(tip_positions(chain, q), _in_plane(want[1:]), rtol=0, atol=ATOL)  # the links' ends
        np.testing.assert_allclose(lg.com_positions(chain, q), _in_plane(want_com), rtol=0, atol=ATOL)


def test_cart_and_slanted_slide_by_hand():
    """A cart on x with a pole, then a slide joint at 0.4 rad to the pole (its axis turns with the pole)."""
    l, c, a = 1.1, 0.4, 0.4
    chain = Chain([Link("prismatic", 3.0, 0.0, com=0.0, inertia=0.0, gear=1.0), Link("revolute", 1.0, l, com=c),
                   Link("prismatic", 0.5, 0.2, com=0.1, axis=a)])
    rng = np.random.default_rng(1)
    for x, th, s in rng.uniform(-2, 2, (20, 3)):
        pivot = np.array([x, 0.0])
        e = np.array([math.cos(th + a), math.sin(th + a)])  # e(phi + axis), phi = th the pole's absolute angle
        slider = pivot + l * _d(th) + s * e
        want = np.stack([pivot, pivot, slider])  # the pole hinges on the cart (length 0)
        tips = np.stack([pivot, pivot + l * _d(th), slider + 0.2 * _d(th)])
        want_com = np.stack([pivot, pivot + c * _d(th), slider + 0.1 * _d(th)])
        q = jnp.array([x, th, s])
        np.testing.assert_allclose(lg.positions(chain, q), _in_plane(want), rtol=0, atol=ATOL)
        np.testing.assert_allclose(tip_positions(chain, q), _in_plane(tips), rtol=0, atol=ATOL)
        np.testing.assert_allclose(lg.com_positions(chain, q), _in_plane(want_com), rtol=0, atol=ATOL)


@pytest.mark.parametrize("batch", [(), (5,), (3, 4)], ids=str)
def test_batch_shapes_and_rows(batch):
    """(*batch, bodies, 3) each, each row the single-state result."""
    chain = lg.systems.double_cartpole()
    q = jnp.asarray(np.random.default_rng(2).uniform(-3, 3, batch + (3,)))
    p, c, t = lg.positions(chain, q), lg.com_positions(chain, q), tip_positions(chain, q)
    assert p.shape == c.shape == t.shape == batch + (3, 3)
    flat_q = q.reshape(-1, 3)
    for i, qi in enumerate(flat_q):
        np.testing.assert_allclose(p.reshape(-1, 3, 3)[i], lg.positions(chain, qi), rtol=0, atol=ATOL)
        np.testing.assert_allclose(c.reshape(-1, 3, 3)[i], lg.com_positions(chain, qi), rtol=0, atol=ATOL)
        np.testing.assert_allclose(t.reshape(-1, 3, 3)[i], tip_positions(chain, qi), rtol=0, atol=ATOL)


def test_frame_jets_are_the_derivatives_of_the_positions():
    """Each centre of mass's jet carries the value, the Jacobian row (``g``), the velocity (``vd``) and the
    second time derivative at zero joint acceleration (``a``) of ``com_positions``: against ``jax.jacfwd`` and
    nested ``jax.jvp`` along qd. The angle rates are the sums of the revolute joints' speeds up to each link."""
    chain = Chain([Link("prismatic", 1.0, 0.3, com=0.1, axis=0.7, gear=1.0), Link("revolute", 1.0, 0.9),
                   Link("revolute", 1.0, 0.6, com=0.2), Link("prismatic", 1.0, 0.5)])
    rng = np.random.default_rng(3)
    q, qd = jnp.asarray(rng.uniform(-2, 2, 4)), jnp.asarray(rng.uniform(-2, 2, 4))
    com = lambda q: lg.com_positions(chain, q)[..., ::2]  # noqa: E731  (x, z)
    value, velocity = jax.jvp(com, (q,), (qd,))
    accel = jax.jvp(lambda q: jax.jvp(com, (q,), (qd,))[1], (q,), (qd,))[1]
    jac = jax.jacfwd(com)(q)  # (n, 2, n)
    f = frames(planar(chain), q, qd)
    for i, point in enumerate(f.com):
        for k, jet in enumerate(point):
            assert abs(float(jet.v) - float(value[i, k])) <= ATOL
            assert abs(float(jet.vd) - float(velocity[i, k])) <= ATOL
            assert abs(float(jet.a) - float(accel[i, k])) <= ATOL
            dense = np.zeros(4)
            for j, d in jet.g.items():
                dense[j] = float(d)
            np.testing.assert_allclose(dense, jac[i, k], rtol=0, atol=ATOL)
    assert f.revolute_before == [(), (1,), (1, 2), (1, 2)]
    np.testing.assert_allclose([float(r) for r in f.angle_rate], [0.0, qd[1], qd[1] + qd[2], qd[1] + qd[2]],
                               rtol=0, atol=ATOL)
    assert all(r is None for r in frames(planar(chain), q).angle_rate)  # no velocities asked for
