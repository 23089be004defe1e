"""The float64 and float32 sines and cosines of lagrange.math.sincos against NumPy's, and their derivatives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange.math.sincos import sincos


@pytest.mark.parametrize("scale", [4.0, 1e2, 1e5])
def test_sincos_matches_numpy_to_an_ulp_of_one(scale):
    x = np.random.default_rng(0).uniform(-scale, scale, 100_000)
    x = np.concatenate([x, np.arange(-64, 65) * (np.pi / 4)])
    s, c = jax.jit(sincos)(jnp.asarray(x))
    assert s.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(s), np.sin(x), rtol=0, atol=2 * np.finfo(float).eps)
    np.testing.assert_allclose(np.asarray(c), np.cos(x), rtol=0, atol=2 * np.finfo(float).eps)


@pytest.mark.parametrize("scale", [4.0, 1e5])
def test_float32_sincos_within_a_float32_ulp_at_one(scale):
    x = np.random.default_rng(1).uniform(-scale, scale, 100_000).astype(np.float32)
    x = np.concatenate([x, (np.arange(-64, 65) * (np.pi / 4)).astype(np.float32)])
    s, c = jax.jit(sincos)(jnp.asarray(x))
    assert s.dtype == c.dtype == jnp.float32
    exact = x.astype(np.float64)  # the float32 angle itself, so only sincos's own error is measured
    eps = float(np.finfo(np.float32).eps)
    np.testing.assert_allclose(np.asarray(s, np.float64), np.sin(exact), rtol=0, atol=eps)
    np.testing.assert_allclose(np.asarray(c, np.float64), np.cos(exact), rtol=0, atol=eps)


def test_sincos_derivatives_and_float32():
    x = 0.7
    ds = jax.grad(lambda x: sincos(x)[0])(x)
    dc = jax.grad(lambda x: sincos(x)[1])(x)
    d2s = jax.grad(jax.grad(lambda x: sincos(x)[0]))(x)
    np.testing.assert_allclose([ds, dc, d2s], [np.cos(x), -np.sin(x), -np.sin(x)], rtol=1e-15)
    s32, c32 = sincos(jnp.linspace(-3, 3, 7, dtype=jnp.float32))
    assert s32.dtype == jnp.float32
    np.testing.assert_allclose(np.asarray(s32), np.sin(np.linspace(-3, 3, 7)), atol=1e-6)
    assert np.all(np.isnan(np.asarray(sincos(jnp.asarray([np.inf, np.nan]))[0])))


@pytest.mark.parametrize("dtype, kept, top", [(jnp.float64, 1e14, 300), (jnp.float32, 1e6, 38)])
def test_sincos_is_bounded_or_nan_at_any_angle(dtype, kept, top):
    """Past the range reduction's reach (angles whose float spacing nears a radian) the values are NaN, never the
    polynomials' unbounded values (1e46 at 1e20 rad before); up to ``kept`` none is NaN."""
    x = np.logspace(0, top, 100_001).astype(dtype)
    x = np.concatenate([x, -x])
    s, c = jax.jit(sincos)(jnp.asarray(x))
    v = np.concatenate([np.asarray(s, np.float64), np.asarray(c, np.float64)])
    assert np.all(np.isnan(v) | (np.abs(v) <= 1.0))
    assert not np.any(np.isnan(v[np.tile(np.abs(x) <= kept, 2)]))
    assert np.all(np.isnan(np.asarray(sincos(jnp.asarray([np.inf, -np.inf], dtype))[1])))
