"""The observation normaliser (policies/normalizer.py) against numpy's mean and variance of the concatenated data,
its clipping, purity and argument check."""

import jax.numpy as jnp
import numpy as np
import pytest

from policies import Normalizer


def test_normalizer_matches_numpy_and_clips():
    rng = np.random.default_rng(0)
    batches = [rng.normal([1.0, -2.0, 0.0], [0.5, 3.0, 1e-3], size=(n, 3)) for n in (7, 50, 13)]
    norm = Normalizer.create(3)
    for b in batches:
        norm = norm.update(jnp.asarray(b))
    data = np.concatenate(batches)
    np.testing.assert_allclose(norm.mean, data.mean(0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(norm.var, data.var(0), rtol=1e-10)
    assert float(norm.count) == len(data)
    z = norm(jnp.asarray(data))
    expected = np.clip((data - data.mean(0)) / np.sqrt(data.var(0) + 1e-6), -5, 5)
    np.testing.assert_allclose(z, expected, rtol=1e-9, atol=1e-12)
    far = norm(jnp.array([1e3, -1e3, 0.0]))
    np.testing.assert_array_equal(far[:2], [5.0, -5.0])
    # pure: the old object is unchanged by an update
    n0 = Normalizer.create(3)
    n0.update(jnp.ones((4, 3)))
    assert float(n0.count) == 0
    # identity (up to clipping) before any data
    np.testing.assert_allclose(n0(jnp.array([0.5, -1.0, 2.0])), [0.5, -1.0, 2.0], rtol=1e-6)


def test_normalizer_validates():
    with pytest.raises(ValueError, match="clip"):
        Normalizer.create(3, clip=0.0)
