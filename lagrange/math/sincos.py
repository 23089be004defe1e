"""``sincos(x)``: the sine and cosine of float64 and float32 angles from one range reduction and two polynomials.

XLA's CPU backend evaluates a float64 ``sin`` or ``cos`` at ~6 ns an element (a scalar call each), and counts them as
cheap enough to recompute in every fused kernel that reads them: the link angles of a long chain ended up computed
several times per step. Here the reduction ``x = k pi/2 + y`` (Cody-Waite, pi/2 in three parts, as fdlibm's
``__ieee754_rem_pio2`` does for medium arguments) and fdlibm's minimax polynomials of ``__kernel_sin`` and
``__kernel_cos`` on ``|y| <= pi/4`` are plain multiplies and adds that XLA vectorises: both values for ~2.3 ns an
element. Measured against NumPy: absolute errors <= 2.3e-16 for ``|x| <= 1e5`` rad, 1.3e-15 at 1e6 and 1.3e-13 at 1e8
(where the angle itself is only known to its spacing, 1.5e-8); ``tests/lagrange/math/test_sincos.py`` holds the first.
From ~7e15 rad (float64; errors up to 9e-6 below it) or ~1e7 rad (float32; 9e-5), where an angle's spacing
reaches one radian and the reduction no longer brings it within pi/2, both values are NaN: the state has blown up,
and ``simulate`` reports it, where the polynomials would return unbounded values (XLA's ``sin`` reduces any
argument, but its values there mean as little as the angle).

XLA's float32 ``sin`` and ``cos`` are no cheaper: ~16 ns an element for both. float32 angles take the same route with
pi/2 in three float32 parts (the first with 8 significant bits, so ``k pi/2`` is exact for ``|x| < 1e5``) and Cephes'
degree-7 and degree-8 minimax polynomials (``sinf.c``): both values for ~1.4 ns an element, absolute errors <= 9e-8
(one float32 ulp at 1 is 1.2e-7; XLA's own are <= 3.2e-8) for ``|x| <= 1e5``. Written with Python constants, so it
needs no ``jax_enable_x64``.

The derivative is given by a ``custom_jvp`` (``d sin = cos dx``, ``d cos = -sin dx``), so reverse mode stores no
polynomial intermediates and higher derivatives come out the same way. Other float types (float16, bfloat16) use
``jnp.sin``/``jnp.cos``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

# fdlibm k_sin.c and k_cos.c
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
# fdlibm e_rem_pio2.c: pi/2 in three 33-bit parts and their tails
_PIO2_1, _PIO2_1T = 1.57079632673412561417e00, 6.07710050650619224932e-11
_PIO2_2, _PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
_PIO2_3, _PIO2_3T = 2.02226624871116645580e-21, 8.47842766036889956997e-32
_INVPIO2 = 6.36619772367581382433e-01
# Cephes sinf.c: minimax polynomials on |y| <= pi/4 and pi/2 in three float32 parts (twice its DP1, DP2, DP3)
_S32 = (-1.6666654611e-1, 8.3321608736e-3, -1.9515295891e-4)
_C32 = (4.166664568298827e-2, -1.388731625493765e-3, 2.443315711809948e-5)
_PIO2_32 = (1.5703125, 4.837512969970703125e-4, 7.54978995489188216e-8)


def _poly(z, c):
    out = c[-1]
    for ci in reversed(c[:-1]):
        out = ci + z * out
    return out


def _sincos64(x):
    k = jnp.round(x * _INVPIO2)
    # y = x - k pi/2 in double-double steps (fdlibm's medium-argument path, both refinements always taken)
    r = x - k * _PIO2_1
    w = k * _PIO2_1T
    y = r - w
    w = k * _PIO2_2
    r2 = r - w
    w = k * _PIO2_2T - ((r - r2) - w)
    y = r2 - w
    w = k * _PIO2_3
    r3 = y - w
    w = k * _PIO2_3T - ((y - r3) - w)
    y = r3 - w
    return _quadrants(k, y, _S, _C)


def _sincos32(x):
    k = jnp.round(x * _INVPIO2)
    y = ((x - k * _PIO2_32[0]) - k * _PIO2_32[1]) - k * _PIO2_32[2]
    return _quadrants(k, y, _S32, _C32)


def _quadrants(k, y, S, C):
    """sin and cos of ``k pi/2 + y`` from the polynomials ``S`` and ``C`` on ``|y| <= pi/4``."""
    z = y * y
    s = y + (y * z) * _poly(z, S)
    c = (1.0 - 0.5 * z) + (z * z) * _poly(z, C)
    quadrant = k - 4.0 * jnp.floor(k * 0.25)  # k mod 4, exact in floating point
    swap = (quadrant == 1.0) | (quadrant == 3.0)
    sin = jnp.where(swap, c, s) * jnp.where(quadrant >= 2.0, -1.0, 1.0)
    cos = jnp.where(swap, s, c) * jnp.where((quadrant == 1.0) | (quadrant == 2.0), -1.0, 1.0)
    # past the reduction's range y is not reduced and the polynomials are unbounded: NaN, not a silent wrong value
    lost = jnp.abs(y) > 1.5707963267948966
    return jnp.where(lost, jnp.nan, sin), jnp.where(lost, jnp.nan, cos)


@jax.custom_jvp
def sincos(x):
    """``(sin(x), cos(x))`` of an array ``x`` (float64 and float32: the polynomials above; other types:
    ``jnp.sin``/``jnp.cos``)."""
    dtype = jnp.result_type(x)
    if dtype == jnp.float64:
        return _sincos64(x)
    if dtype == jnp.float32:
        return _sincos32(x)
    return jnp.sin(x), jnp.cos(x)


@sincos.defjvp
def _sincos_jvp(primals, tangents):
    (x,), (dx,) = primals, tangents
    s, c = sincos(x)
    return (s, c), (c * dx, s * (-1.0 * dx))
