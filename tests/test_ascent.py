"""benchmarks/_ascent.py: the Adam ascent that keeps the best iterate it has seen."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from benchmarks._ascent import adam_best_seen


def test_climbs_a_concave_objective_to_its_top():
    z, best, start = adam_best_seen(lambda z: -jnp.sum((z - 2.0) ** 2), jnp.zeros(3), steps=300, learning_rate=0.1)
    assert float(start) == -12.0
    np.testing.assert_allclose(z, 2.0, atol=1e-2)
    assert -1e-3 < float(best) <= 0.0


def test_keeps_the_best_iterate_when_the_last_is_worse():
    # the value is a narrow bump at 0.5 on a slope that keeps rising: the optimiser passes the bump...
    value = lambda z: jnp.where(jnp.abs(z[0] - 0.5) < 0.05, 10.0, z[0])
    z, best, _ = adam_best_seen(value, jnp.zeros(1), steps=50, learning_rate=0.1)
    assert float(best) == 10.0 and abs(float(z[0]) - 0.5) < 0.05


def test_a_non_finite_start_is_beaten_by_any_finite_iterate():
    # NaN at the start only: before the fix the NaN start was kept as "best" (v > NaN is always false)
    value = lambda z: -((z[0] - 1.0) ** 2) + jnp.where(z[0] == 0.0, jnp.nan, 0.0)  # gradient finite throughout
    z, best, start = adam_best_seen(value, jnp.zeros(1), steps=100, learning_rate=0.05)
    assert np.isnan(float(start))
    assert np.isfinite(float(best)) and float(best) > -1.0 and float(z[0]) != 0.0


def test_nothing_finite_gives_minus_infinity_and_the_start():
    z, best, _ = adam_best_seen(lambda z: jnp.sum(z) * jnp.nan, jnp.ones(2), steps=5, learning_rate=0.1)
    assert float(best) == -np.inf
    np.testing.assert_array_equal(z, jnp.ones(2))
