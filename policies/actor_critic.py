"""SHAC's actor and critic (Xu et al. 2022, as in NVlabs/DiffRL): MLPs ``[64, 64]`` of Linear -> ELU -> LayerNorm.

The actor's output layer is linear (the mean) and its log-std a state-independent vector initialised to
-1; its layers keep equinox's default (PyTorch-style uniform) initialisation. The critic's layers are
orthogonal with gain sqrt(2) and zero biases, as in the authors' code. As a rollout policy
(:class:`policies.AbstractPolicy`) the actor acts deterministically, its evaluation action ``tanh(mu(obs))``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import DTypeLike
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from policies.base import AbstractFeedForwardPolicy, check_size

__all__ = ["Actor", "Critic"]


def _units(cls: str, units) -> tuple[int, ...]:
    """The hidden widths as a tuple of integers >= 1, or a ``ValueError`` naming ``units``."""
    if isinstance(units, (str, bytes)) or not isinstance(units, Sequence):
        raise ValueError(f"{cls} units must be a sequence of integers >= 1 (the hidden widths), got {units!r}")
    return tuple(check_size(cls, f"units[{i}]", u) for i, u in enumerate(units))


class _MLP(eqx.Module):
    """Linear -> ELU -> LayerNorm for each hidden layer, then a linear output (all non-arrays static)."""

    hidden: tuple[eqx.nn.Linear, ...]
    norms: tuple[eqx.nn.LayerNorm, ...]
    out: eqx.nn.Linear

    def __init__(self, in_size: int, out_size: int, units: tuple[int, ...], *, orthogonal_gain: float | None,
                 key: PRNGKeyArray, dtype: DTypeLike | None = None):
        keys = jax.random.split(key, len(units) + 1)
        sizes = (in_size,) + tuple(units)
        layers = [eqx.nn.Linear(a, b, dtype=dtype, key=k) for a, b, k in zip(sizes[:-1], sizes[1:], keys)]
        out = eqx.nn.Linear(sizes[-1], out_size, dtype=dtype, key=keys[-1])
        if orthogonal_gain is not None:  # the authors' critic: orthogonal weights, zero biases
            init = jax.nn.initializers.orthogonal(orthogonal_gain)

            def ortho(lin, k):
                w = init(k, lin.weight.shape, lin.weight.dtype)
                return eqx.tree_at(lambda m: (m.weight, m.bias), lin, (w, jnp.zeros_like(lin.bias)))

            wkeys = jax.random.split(jax.random.fold_in(key, 1), len(units) + 1)
            layers = [ortho(lin, k) for lin, k in zip(layers, wkeys)]
            out = ortho(out, wkeys[-1])
        self.hidden = tuple(layers)
        self.norms = tuple(eqx.nn.LayerNorm(u, eps=1e-5, dtype=dtype) for u in units)
        self.out = out

    def __call__(self, x: Float[ArrayLike, " in_size"]) -> Float[Array, " out_size"]:
        for lin, norm in zip(self.hidden, self.norms):
            x = norm(jax.nn.elu(lin(x)))
        return self.out(x)


@final
class Actor(AbstractFeedForwardPolicy):
    """Stochastic tanh-Gaussian actor: ``a = tanh(mu(obs) + exp(log_std) eps)``, ``eps ~ N(0, I)``
    (:meth:`sample`); ``log_std`` (action_size,) does not depend on the state. ``obs`` is the normalised
    observation. As a rollout policy, ``actor(obs, hidden, reset) -> (action, hidden)`` with an empty hidden
    state, it acts deterministically: ``tanh(mu(obs))`` (:meth:`deterministic`, the evaluation action).
    Unbatched: ``jax.vmap`` the methods over environments.

    Args:
        obs_size: length of the (normalised) observation vector.
        action_size: number of actions (dimensionless, in ``(-1, 1)``; the task multiplies them by the
            chain's gear).
        units: widths of the hidden layers of ``mu``.
        init_log_std: initial value of every component of ``log_std`` (log of a dimensionless std).
        key: PRNG key for the initial weights.
        dtype: floating dtype of the weights; ``None`` for JAX's default.
    """

    mu: _MLP
    log_std: Float[Array, " action_size"]
    init_log_std: float = eqx.field(static=True)
    hidden_size: int = eqx.field(static=True, default=0)

    def __init__(self, obs_size: int, action_size: int, units: Sequence[int] = (64, 64), init_log_std: float = -1.0,
                 *, key: PRNGKeyArray, dtype: DTypeLike | None = None):
        obs_size = check_size("Actor", "obs_size", obs_size)
        action_size = check_size("Actor", "action_size", action_size)
        units = _units("Actor", units)
        if isinstance(init_log_std, bool) or not np.isfinite(init_log_std):
            raise ValueError(f"Actor init_log_std must be a finite number, got {init_log_std!r}")
        self.mu = _MLP(obs_size, action_size, units, orthogonal_gain=None, key=key, dtype=dtype)
        self.log_std = jnp.full(action_size, init_log_std, self.mu.out.weight.dtype)
        self.init_log_std = float(init_log_std)
        self.hidden_size = 0

    def reinit(self, key: PRNGKeyArray) -> "Actor":
        """The same architecture (sizes, ``init_log_std`` and dtype) with fresh initial weights.

        Args:
            key: PRNG key of the new weights.
        """
        units = tuple(layer.out_features for layer in self.mu.hidden)
        return Actor(self.mu.hidden[0].in_features if units else self.mu.out.in_features, self.log_std.shape[0],
                     units, self.init_log_std, key=key, dtype=self.mu.out.weight.dtype)

    def sample(self, obs: Float[ArrayLike, " obs_size"], key: PRNGKeyArray) -> Float[Array, " action_size"]:
        """A reparameterised stochastic action in (-1, 1) (differentiable in the parameters and ``obs``).

        Args:
            obs: the normalised observation, shape ``(obs_size,)``.
            key: PRNG key for the Gaussian noise ``eps``.

        Returns:
            The action, shape ``(action_size,)``, dimensionless.
        """
        mu = self.mu(obs)
        eps = jax.random.normal(key, mu.shape, mu.dtype)
        return jnp.tanh(mu + jnp.exp(self.log_std) * eps)

    def deterministic(self, obs: Float[ArrayLike, " obs_size"]) -> Float[Array, " action_size"]:
        """The evaluation action ``tanh(mu(obs))``.

        Args:
            obs: the normalised observation, shape ``(obs_size,)``.

        Returns:
            The action in ``(-1, 1)``, shape ``(action_size,)``, dimensionless.
        """
        return jnp.tanh(self.mu(obs))


class Critic(eqx.Module):
    """State-value critic ``V(obs)`` (scalar) on normalised observations. Unbatched: ``jax.vmap`` it
    over environments.

    Args:
        obs_size: length of the (normalised) observation vector.
        units: widths of the hidden layers.
        key: PRNG key for the initial weights.
        dtype: floating dtype of the weights; ``None`` for JAX's default.
    """

    net: _MLP

    def __init__(self, obs_size: int, units: Sequence[int] = (64, 64), *, key: PRNGKeyArray,
                 dtype: DTypeLike | None = None):
        obs_size, units = check_size("Critic", "obs_size", obs_size), _units("Critic", units)
        self.net = _MLP(obs_size, 1, units, orthogonal_gain=float(np.sqrt(2.0)), key=key, dtype=dtype)

    def __call__(self, obs: Float[ArrayLike, " obs_size"]) -> Float[Array, ""]:
        """The value of an observation.

        Args:
            obs: the normalised observation, shape ``(obs_size,)``.

        Returns:
            A scalar, in the task's reward units (a discounted sum of rewards).
        """
        return self.net(obs)[0]
