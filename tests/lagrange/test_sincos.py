"""The float64 sine and cosine of lagrange._sincos against NumPy's, and their derivatives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange._sincos import sincos


@pytest.mark.parametrize("scale", [4.0, 1e2, 1e5])
def test_sincos_matches_numpy_to_an_ulp_of_one(scale):
    x = np.random.default_rng(0).uniform(-scale, scale, 100_000)
    x = np.concatenate([x, np.arange(-64, 65) * (np.pi / 4)])
    s, c = jax.jit(sincos)(jnp.asarray(x))
    assert s.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(s), np.sin(x), rtol=0, atol=2 * np.finfo(float).eps)
    np.testing.assert_allclose(np.asarray(c), np.cos(x), rtol=0, atol=2 * np.finfo(float).eps)


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
