"""Hand-written closed-form equations of motion: the independent oracle of the tests and the benchmarks' reference.

``tests/lagrange/test_dynamics.py`` and ``tests/lagrange/test_systems.py`` check ``lagrange``'s mass matrices, bias
forces and rollouts against them; ``benchmarks/derivation_overhead.py``, ``benchmarks/throughput.py`` and
``research/xla_vectorization.py`` time ``lagrange`` against them (what the derivation costs beside equations written
by hand). All import it as ``oracles.closed_form`` (from the repository root).

Written the way a careful person writes them by hand: scalar expressions, every sine and cosine
evaluated once and shared, ``sin(a + b)`` from the angle-sum identity, an explicit 2x2 inverse
and a 3x3 adjugate solve. No ``jnp.linalg``, no autodiff, no code shared with ``lagrange``.

Conventions are those of :mod:`lagrange.chain` and the defaults those of :mod:`lagrange.systems`:
planar x-z, gravity along -z, a link at absolute angle ``phi`` points along
``d(phi) = (sin phi, -cos phi)`` (``q = 0`` hangs down), angles are relative joint angles, the
centre of mass sits at ``com = length / 2`` and ``inertia = mass length^2 / 12`` is about it
(thin rod), the cart slides along x. With ``s_i = sin`` and ``c_i = cos`` of the absolute angles:

pendulum ``q = (th,)``::

    M = m lc^2 + I,   bias = m g lc s + b thd,   B = (gear,)

cartpole ``q = (x, th)`` (cart mass ``mc``, pole ``mp, lc, I``)::

    M = [[mc + mp, mp lc c], [mp lc c, mp lc^2 + I]]
    bias = (-mp lc s thd^2 + b xd,  mp g lc s),   B = (gear, 0)

acrobot ``q = (q1, q2)``, ``h = m2 l1 lc2 sin q2``::

    M11 = I1 + I2 + m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2)
    M12 = I2 + m2 (lc2^2 + l1 lc2 cos q2),   M22 = I2 + m2 lc2^2
    C qd = (-h (2 q1d q2d + q2d^2),  h q1d^2)
    T = (m1 g lc1 s1 + m2 g (l1 s1 + lc2 s12),  m2 g lc2 s12),   B = (0, gear)

double cartpole ``q = (x, t1, t2)``, ``w = t1d + t2d``, ``h = m2 l1 lc2 sin t2``::

    Mxx = mc + m1 + m2,  Mx1 = (m1 lc1 + m2 l1) c1 + m2 lc2 c12,  Mx2 = m2 lc2 c12
    M11 = I1 + I2 + m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 c2)
    M12 = I2 + m2 (lc2^2 + l1 lc2 c2),  M22 = I2 + m2 lc2^2
    C qd = (-(m1 lc1 + m2 l1) s1 t1d^2 - m2 lc2 s12 w^2,  h (t1d^2 - w^2),  h t1d^2)
    T = (0,  (m1 lc1 + m2 l1) g s1 + m2 g lc2 s12,  m2 g lc2 s12),   B = (gear, 0, 0)

``bias`` is ``C qd + T + damping qd`` (the damping terms vanish at the default ``damping = 0``),
as :func:`lagrange.bias_forces`. Every function takes ``q``, ``qd``, ``u`` with any leading batch
dimensions and a ``params`` NamedTuple of floats or arrays, so it can be jitted, vmapped and
differentiated.

:func:`rk4_step` and :func:`rollout` are the matching hand-written classic RK4 integrator and a
``lax.scan`` rollout with controls held constant over each interval.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple
from collections.abc import Callable

import jax
import jax.numpy as jnp


def _stack(*xs):
    xs = [jnp.asarray(x) for x in xs]
    shape = jnp.broadcast_shapes(*(x.shape for x in xs))
    return jnp.stack([jnp.broadcast_to(x, shape) for x in xs], axis=-1)


def _solve2(a, b, d, r0, r1):
    """Solve [[a, b], [b, d]] x = r by the explicit inverse."""
    inv_det = 1.0 / (a * d - b * b)
    return (d * r0 - b * r1) * inv_det, (a * r1 - b * r0) * inv_det


def _solve3(a, b, c, d, e, f, r0, r1, r2):
    """Solve the symmetric [[a, b, c], [b, d, e], [c, e, f]] x = r by the adjugate."""
    A00 = d * f - e * e
    A01 = c * e - b * f
    A02 = b * e - c * d
    A11 = a * f - c * c
    A12 = b * c - a * e
    A22 = a * d - b * b
    inv_det = 1.0 / (a * A00 + b * A01 + c * A02)
    x0 = (A00 * r0 + A01 * r1 + A02 * r2) * inv_det
    x1 = (A01 * r0 + A11 * r1 + A12 * r2) * inv_det
    x2 = (A02 * r0 + A12 * r1 + A22 * r2) * inv_det
    return x0, x1, x2


# --------------------------------------------------------------------------- pendulum


class PendulumParams(NamedTuple):
    """``lagrange.systems.pendulum()`` defaults."""

    mass: float = 1.0
    length: float = 1.0
    com: float = 0.5
    inertia: float = 1.0 / 12.0
    damping: float = 0.0
    gear: float = 1.0
    gravity: float = 9.81


def pendulum_mass_matrix(p: PendulumParams, q):
    M = p.mass * p.com * p.com + p.inertia
    return jnp.broadcast_to(M, q[..., 0].shape)[..., None, None]


def pendulum_gravity(p: PendulumParams, q):
    return (p.mass * p.gravity * p.com * jnp.sin(q[..., 0]))[..., None]


def pendulum_bias(p: PendulumParams, q, qd):
    return (p.mass * p.gravity * p.com * jnp.sin(q[..., 0]) + p.damping * qd[..., 0])[..., None]


def pendulum_forward_dynamics(p: PendulumParams, q, qd, u):
    tau = p.gear * u[..., 0] - p.mass * p.gravity * p.com * jnp.sin(q[..., 0]) - p.damping * qd[..., 0]
    return (tau / (p.mass * p.com * p.com + p.inertia))[..., None]


# --------------------------------------------------------------------------- cartpole


class CartpoleParams(NamedTuple):
    """``lagrange.systems.cartpole()`` defaults (``damping`` acts on the cart)."""

    cart_mass: float = 10.47
    pole_mass: float = 5.02
    pole_length: float = 1.0
    pole_com: float = 0.5
    pole_inertia: float = 5.02 / 12.0
    damping: float = 0.0
    gear: float = 100.0
    gravity: float = 9.81


def _cartpole_m(p, c):
    ml = p.pole_mass * p.pole_com
    a = p.cart_mass + p.pole_mass
    b = ml * c
    d = ml * p.pole_com + p.pole_inertia
    return a, b, d


def cartpole_mass_matrix(p: CartpoleParams, q):
    a, b, d = _cartpole_m(p, jnp.cos(q[..., 1]))
    return jnp.stack([_stack(a, b), _stack(b, d)], axis=-2)


def cartpole_gravity(p: CartpoleParams, q):
    s = jnp.sin(q[..., 1])
    return _stack(jnp.zeros_like(s), p.pole_mass * p.gravity * p.pole_com * s)


def cartpole_bias(p: CartpoleParams, q, qd):
    s = jnp.sin(q[..., 1])
    ml = p.pole_mass * p.pole_com
    thd = qd[..., 1]
    return _stack(-ml * s * thd * thd + p.damping * qd[..., 0], ml * p.gravity * s)


def cartpole_forward_dynamics(p: CartpoleParams, q, qd, u):
    s, c = jnp.sin(q[..., 1]), jnp.cos(q[..., 1])
    ml = p.pole_mass * p.pole_com
    thd = qd[..., 1]
    a, b, d = _cartpole_m(p, c)
    r0 = p.gear * u[..., 0] + ml * s * thd * thd - p.damping * qd[..., 0]
    r1 = -ml * p.gravity * s
    return _stack(*_solve2(a, b, d, r0, r1))


# --------------------------------------------------------------------------- acrobot


class AcrobotParams(NamedTuple):
    """``lagrange.systems.acrobot()`` defaults (``damping`` acts on both joints)."""

    m1: float = 2.5
    m2: float = 2.5
    l1: float = 1.0
    l2: float = 1.0
    lc1: float = 0.5
    lc2: float = 0.5
    I1: float = 2.5 / 12.0
    I2: float = 2.5 / 12.0
    damping: float = 0.0
    gear: float = 25.0
    gravity: float = 9.81


def _acrobot_terms(p, q):
    s1, c1 = jnp.sin(q[..., 0]), jnp.cos(q[..., 0])
    s2, c2 = jnp.sin(q[..., 1]), jnp.cos(q[..., 1])
    s12 = s1 * c2 + c1 * s2
    k = p.m2 * p.l1 * p.lc2
    M22 = p.I2 + p.m2 * p.lc2 * p.lc2
    M12 = M22 + k * c2
    M11 = p.I1 + p.m1 * p.lc1 * p.lc1 + p.m2 * p.l1 * p.l1 + M22 + 2.0 * k * c2
    g2 = p.m2 * p.gravity * p.lc2 * s12
    g1 = (p.m1 * p.lc1 + p.m2 * p.l1) * p.gravity * s1 + g2
    return M11, M12, M22, k * s2, g1, g2


def acrobot_mass_matrix(p: AcrobotParams, q):
    M11, M12, M22, *_ = _acrobot_terms(p, q)
    return jnp.stack([_stack(M11, M12), _stack(M12, M22)], axis=-2)


def acrobot_gravity(p: AcrobotParams, q):
    *_, g1, g2 = _acrobot_terms(p, q)
    return _stack(g1, g2)


def _acrobot_bias(p, h, g1, g2, qd):
    q1d, q2d = qd[..., 0], qd[..., 1]
    b1 = g1 - h * (2.0 * q1d + q2d) * q2d + p.damping * q1d
    b2 = g2 + h * q1d * q1d + p.damping * q2d
    return b1, b2


def acrobot_bias(p: AcrobotParams, q, qd):
    _, _, _, h, g1, g2 = _acrobot_terms(p, q)
    return _stack(*_acrobot_bias(p, h, g1, g2, qd))


def acrobot_forward_dynamics(p: AcrobotParams, q, qd, u):
    M11, M12, M22, h, g1, g2 = _acrobot_terms(p, q)
    b1, b2 = _acrobot_bias(p, h, g1, g2, qd)
    return _stack(*_solve2(M11, M12, M22, -b1, p.gear * u[..., 0] - b2))


# --------------------------------------------------------------------------- double cartpole


class DoubleCartpoleParams(NamedTuple):
    """``lagrange.systems.double_cartpole()`` defaults (``damping`` acts on the cart)."""

    cart_mass: float = 10.47
    m1: float = 5.02
    m2: float = 5.02
    l1: float = 1.0
    l2: float = 1.0
    lc1: float = 0.5
    lc2: float = 0.5
    I1: float = 5.02 / 12.0
    I2: float = 5.02 / 12.0
    damping: float = 0.0
    gear: float = 1000.0
    gravity: float = 9.81


def _double_terms(p, q):
    s1, c1 = jnp.sin(q[..., 1]), jnp.cos(q[..., 1])
    s2, c2 = jnp.sin(q[..., 2]), jnp.cos(q[..., 2])
    s12 = s1 * c2 + c1 * s2
    c12 = c1 * c2 - s1 * s2
    a1 = p.m1 * p.lc1 + p.m2 * p.l1  # first-moment of everything the first pole carries
    a2 = p.m2 * p.lc2
    k = a2 * p.l1
    Mxx = p.cart_mass + p.m1 + p.m2
    Mx2 = a2 * c12
    Mx1 = a1 * c1 + Mx2
    M22 = p.I2 + a2 * p.lc2
    M12 = M22 + k * c2
    M11 = p.I1 + p.m1 * p.lc1 * p.lc1 + p.m2 * p.l1 * p.l1 + M22 + 2.0 * k * c2
    M = (Mxx, Mx1, Mx2, M11, M12, M22)
    trig = (s1, s12, s2)
    return M, trig, a1, a2, k


def double_cartpole_mass_matrix(p: DoubleCartpoleParams, q):
    (Mxx, Mx1, Mx2, M11, M12, M22), *_ = _double_terms(p, q)
    return jnp.stack([_stack(Mxx, Mx1, Mx2), _stack(Mx1, M11, M12), _stack(Mx2, M12, M22)], axis=-2)


def _double_gravity(p, trig, a1, a2):
    s1, s12, _ = trig
    g2 = p.gravity * a2 * s12
    return jnp.zeros_like(s1), p.gravity * a1 * s1 + g2, g2


def double_cartpole_gravity(p: DoubleCartpoleParams, q):
    _, trig, a1, a2, _ = _double_terms(p, q)
    return _stack(*_double_gravity(p, trig, a1, a2))


def _double_bias(p, trig, a1, a2, k, qd):
    s1, s12, s2 = trig
    xd, t1d, t2d = qd[..., 0], qd[..., 1], qd[..., 2]
    w = t1d + t2d
    w2, t1d2 = w * w, t1d * t1d
    h = k * s2
    _, g1, g2 = _double_gravity(p, trig, a1, a2)
    bx = -a1 * s1 * t1d2 - a2 * s12 * w2 + p.damping * xd
    b1 = g1 + h * (t1d2 - w2)
    b2 = g2 + h * t1d2
    return bx, b1, b2


def double_cartpole_bias(p: DoubleCartpoleParams, q, qd):
    _, trig, a1, a2, k = _double_terms(p, q)
    return _stack(*_double_bias(p, trig, a1, a2, k, qd))


def double_cartpole_forward_dynamics(p: DoubleCartpoleParams, q, qd, u):
    (Mxx, Mx1, Mx2, M11, M12, M22), trig, a1, a2, k = _double_terms(p, q)
    bx, b1, b2 = _double_bias(p, trig, a1, a2, k, qd)
    return _stack(*_solve3(Mxx, Mx1, Mx2, M11, M12, M22, p.gear * u[..., 0] - bx, -b1, -b2))


# --------------------------------------------------------------------------- integration


def rk4_step(fd: Callable, params, q, qd, u, h):
    """One classic RK4 step of ``(q, qd)' = (qd, fd(params, q, qd, u))`` with ``u`` held constant."""
    k1q, k1v = qd, fd(params, q, qd, u)
    q2, v2 = q + 0.5 * h * k1q, qd + 0.5 * h * k1v
    k2q, k2v = v2, fd(params, q2, v2, u)
    q3, v3 = q + 0.5 * h * k2q, qd + 0.5 * h * k2v
    k3q, k3v = v3, fd(params, q3, v3, u)
    q4, v4 = q + h * k3q, qd + h * k3v
    k4q, k4v = v4, fd(params, q4, v4, u)
    q1 = q + (h / 6.0) * (k1q + 2.0 * k2q + 2.0 * k3q + k4q)
    qd1 = qd + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return q1, qd1


def rollout(fd: Callable, params, q0, qd0, controls, dt, substeps: int = 1):
    """RK4 rollout under piecewise-constant ``controls`` ``(T, m)``; ``substeps`` RK4 steps per interval.

    Returns ``(q, qd)`` of shape ``(T + 1, n)`` (``(T + 1, ..., n)`` with batched states), the
    initial state first, like :class:`lagrange.Trajectory`.
    """
    h = dt / substeps

    def interval(carry, u):
        q, qd = carry
        if substeps == 1:
            q, qd = rk4_step(fd, params, q, qd, u, h)
        else:
            q, qd = jax.lax.scan(lambda c, _: (rk4_step(fd, params, *c, u, h), None), (q, qd), None, length=substeps)[0]
        return (q, qd), (q, qd)

    _, (qs, qds) = jax.lax.scan(interval, (q0, qd0), controls)
    return jnp.concatenate([q0[None], qs]), jnp.concatenate([qd0[None], qds])


# --------------------------------------------------------------------------- per-system namespaces


def _system(params, mass_matrix, bias, gravity, forward_dynamics):
    return SimpleNamespace(Params=params, mass_matrix=mass_matrix, bias=bias, gravity=gravity,
                           forward_dynamics=forward_dynamics)


pendulum = _system(PendulumParams, pendulum_mass_matrix, pendulum_bias, pendulum_gravity, pendulum_forward_dynamics)
cartpole = _system(CartpoleParams, cartpole_mass_matrix, cartpole_bias, cartpole_gravity, cartpole_forward_dynamics)
acrobot = _system(AcrobotParams, acrobot_mass_matrix, acrobot_bias, acrobot_gravity, acrobot_forward_dynamics)
double_cartpole = _system(DoubleCartpoleParams, double_cartpole_mass_matrix, double_cartpole_bias,
                          double_cartpole_gravity, double_cartpole_forward_dynamics)
"""``closed_form.<system>.mass_matrix(params, q)``, ``.bias(params, q, qd)``, ``.gravity(params, q)``,
``.forward_dynamics(params, q, qd, u)`` and ``.Params()`` (the defaults of ``lagrange.systems``)."""

SYSTEMS = {"pendulum": pendulum, "cartpole": cartpole, "acrobot": acrobot, "double_cartpole": double_cartpole}
