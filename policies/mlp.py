"""A feed-forward policy for the baselines, with the same call signature as :class:`GRUPolicy`."""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import DTypeLike
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from policies.base import AbstractFeedForwardPolicy, check_size

__all__ = ["MLPPolicy"]


@final
class MLPPolicy(AbstractFeedForwardPolicy):
    """Deterministic MLP: ``depth`` hidden layers of ``width`` with ReLU, then Dense(action) + tanh.

    Stateless, but it takes and returns a (0,)-sized hidden state so that rollouts treat every
    policy alike: ``policy(obs, hidden, reset) -> (action, hidden)``.

    Args:
        obs_size: length of the (normalised) observation vector, >= 1.
        action_size: number of actions, >= 1 (dimensionless, in ``[-1, 1]``; the task multiplies
            them by the chain's gear).
        width: width of each hidden layer, >= 1.
        depth: number of hidden layers, >= 0 (0: one linear layer, then tanh).
        key: PRNG key for the initial weights.
        dtype: floating dtype of the weights; ``None`` for JAX's default.
    """

    mlp: eqx.nn.MLP
    hidden_size: int = eqx.field(static=True, default=0)

    def __init__(self, obs_size: int, action_size: int, width: int = 64, depth: int = 2, *, key: PRNGKeyArray,
                 dtype: DTypeLike | None = None):
        obs_size, action_size, width = (check_size("MLPPolicy", name, v) for name, v in (
            ("obs_size", obs_size), ("action_size", action_size), ("width", width)))
        depth = check_size("MLPPolicy", "depth", depth, 0)
        self.mlp = eqx.nn.MLP(obs_size, action_size, width, depth, activation=jax.nn.relu,
                              final_activation=jnp.tanh, dtype=dtype, key=key)
        self.hidden_size = 0

    def reinit(self, key: PRNGKeyArray) -> "MLPPolicy":
        """The same architecture (sizes, depth and dtype) with fresh initial weights.

        Args:
            key: PRNG key of the new weights.
        """
        m = self.mlp
        return MLPPolicy(m.in_size, m.out_size, m.width_size, m.depth, key=key, dtype=m.layers[-1].weight.dtype)

    def deterministic(self, obs: Float[ArrayLike, " obs_size"]) -> Float[Array, " action_size"]:
        """The action ``mlp(obs)`` in ``(-1, 1)``, shape ``(action_size,)`` (unbatched; ``jax.vmap`` it over
        environments).

        Args:
            obs: the (normalised) observation, shape ``(obs_size,)``.
        """
        return self.mlp(obs)
