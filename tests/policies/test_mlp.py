"""The feed-forward policy (policies/mlp.py): shapes, bounded actions, the parameter count of its layout and the
width check."""

import jax
import jax.numpy as jnp
import pytest

from policies import MLPPolicy
from tests.helpers import param_count


def test_mlp_shapes():
    pol = MLPPolicy(8, 1, 32, key=jax.random.PRNGKey(0))
    a, h = pol(jnp.ones(8), pol.initial_state(), True)
    assert a.shape == (1,) and h.shape == (0,) and float(jnp.abs(a).max()) <= 1
    assert param_count(pol) == 8 * 32 + 32 + 32 * 32 + 32 + 32 + 1
    with pytest.raises(ValueError, match="width"):
        MLPPolicy(8, 1, 0, key=jax.random.PRNGKey(0))
