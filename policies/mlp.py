"""A feed-forward policy for the baselines, with the same call signature as :class:`GRUPolicy`."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp


class MLPPolicy(eqx.Module):
    """Deterministic MLP: ``depth`` hidden layers of ``width`` with ReLU, then Dense(action) + tanh.

    Stateless, but it takes and returns a (0,)-sized hidden state so that rollouts treat every
    policy alike: ``policy(obs, hidden, reset) -> (action, hidden)``.
    """

    mlp: eqx.nn.MLP
    hidden_size: int = eqx.field(static=True, default=0)

    def __init__(self, obs_size: int, action_size: int, width: int = 64, depth: int = 2, *, key, dtype=None):
        for name, v in (("obs_size", obs_size), ("action_size", action_size), ("width", width)):
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"MLPPolicy {name} must be an integer >= 1, got {v!r}")
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 0:
            raise ValueError(f"MLPPolicy depth must be an integer >= 0, got {depth!r}")
        self.mlp = eqx.nn.MLP(obs_size, action_size, width, depth, activation=jax.nn.relu,
                              final_activation=jnp.tanh, dtype=dtype, key=key)
        self.hidden_size = 0

    def initial_state(self) -> jax.Array:
        return jnp.zeros(0, self.mlp.layers[-1].weight.dtype)

    def __call__(self, obs, hidden, reset=False):
        return self.mlp(obs), hidden
