"""The CE-APG authors' recurrent policy, on :class:`equinox.nn.GRUCell`."""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import DTypeLike
from jaxtyping import Array, ArrayLike, Bool, Float, PRNGKeyArray

from policies.base import AbstractPolicy, check_size

__all__ = ["GRUPolicy"]


@final
class GRUPolicy(AbstractPolicy):
    """Deterministic recurrent policy: Dense(H)+ReLU -> GRU cell (hidden size = observation size)
    -> Dense(H)+ReLU -> Dense(H)+ReLU -> Dense(action) + tanh (the authors' layout; H = 16, or 32
    for the double cartpole).

    The hidden state is explicit: ``policy(obs, hidden, reset) -> (action, hidden)`` with
    ``obs`` (obs_size,), ``hidden`` (obs_size,) and actions in ``[-1, 1]`` (action_size,). When
    ``reset`` is true (an episode starts) the incoming hidden state is replaced by zeros.

    Args:
        obs_size: length of the (normalised) observation vector, >= 1; also the GRU's hidden size.
        action_size: number of actions, >= 1 (dimensionless, in ``[-1, 1]``; the task multiplies
            them by the chain's gear).
        width: ``H``, the width of the dense layers, >= 1.
        key: PRNG key for the initial weights.
        dtype: floating dtype of the weights; ``None`` for JAX's default.
    """

    embed: eqx.nn.Linear
    cell: eqx.nn.GRUCell
    fc1: eqx.nn.Linear
    fc2: eqx.nn.Linear
    head: eqx.nn.Linear
    hidden_size: int = eqx.field(static=True)

    def __init__(self, obs_size: int, action_size: int, width: int = 16, *, key: PRNGKeyArray,
                 dtype: DTypeLike | None = None):
        obs_size, action_size, width = (check_size("GRUPolicy", name, v) for name, v in (
            ("obs_size", obs_size), ("action_size", action_size), ("width", width)))
        k = jax.random.split(key, 5)
        self.embed = eqx.nn.Linear(obs_size, width, dtype=dtype, key=k[0])
        self.cell = eqx.nn.GRUCell(width, obs_size, dtype=dtype, key=k[1])
        self.fc1 = eqx.nn.Linear(obs_size, width, dtype=dtype, key=k[2])
        self.fc2 = eqx.nn.Linear(width, width, dtype=dtype, key=k[3])
        self.head = eqx.nn.Linear(width, action_size, dtype=dtype, key=k[4])
        self.hidden_size = obs_size

    def reinit(self, key: PRNGKeyArray) -> "GRUPolicy":
        """The same architecture (sizes and dtype) with fresh initial weights.

        Args:
            key: PRNG key of the new weights.
        """
        return GRUPolicy(self.hidden_size, self.head.out_features, self.embed.out_features, key=key,
                         dtype=self.fc1.weight.dtype)

    def __call__(
        self,
        obs: Float[ArrayLike, " obs_size"],
        hidden: Float[Array, " obs_size"],
        reset: Bool[ArrayLike, ""] = False,
    ) -> tuple[Float[Array, " action_size"], Float[Array, " obs_size"]]:
        """One step of the policy, as :meth:`AbstractPolicy.__call__` (unbatched; ``jax.vmap`` it over environments);
        the hidden state has shape ``(obs_size,)`` and a true ``reset`` zeroes it first."""
        hidden = jnp.where(reset, jnp.zeros_like(hidden), hidden)
        x = jax.nn.relu(self.embed(obs))
        hidden = self.cell(x, hidden)
        x = jax.nn.relu(self.fc1(hidden))
        x = jax.nn.relu(self.fc2(x))
        return jnp.tanh(self.head(x)), hidden
