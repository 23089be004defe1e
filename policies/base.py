"""What every policy is: :class:`AbstractPolicy`, the rollout interface the optimisers and ``optim.episode`` use."""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractVar
from jax.typing import DTypeLike
from jaxtyping import Array, ArrayLike, Bool, Float, PRNGKeyArray

__all__ = ["AbstractPolicy", "AbstractFeedForwardPolicy", "check_size"]


def check_size(cls: str, name: str, value, minimum: int = 1) -> int:
    """Check a layer size or count and return it as an ``int``.

    Args:
        cls: the class name the error gives.
        name: the argument's name.
        value: an integer (a NumPy integer too; not a bool).
        minimum: the smallest allowed.

    Raises:
        ValueError: ``<cls> <name> must be an integer >= <minimum>, got <value>``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{cls} {name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


class AbstractPolicy(eqx.Module):
    """A policy with an explicit hidden state: ``policy(obs, hidden, reset) -> (action, hidden)``, unbatched
    (``jax.vmap`` it over environments). Subclasses are final; each builds itself from the sizes of a task
    (:meth:`for_task`) and can redraw its weights (:meth:`reinit`), which is how the trainers start a run.

    Attributes:
        hidden_size (int): length of the hidden state (0 for a stateless policy); static.
    """

    hidden_size: AbstractVar[int]

    @classmethod
    def for_task(cls, task, *args, key: PRNGKeyArray | None = None, dtype: DTypeLike | None = None, **kwargs):
        """A policy sized for ``task``: ``cls(task.observation_size, task.action_size, *args, key=key, dtype=dtype,
        **kwargs)``.

        Args:
            task: a task of :mod:`lagrange.tasks` (its ``observation_size`` and ``action_size``).
            *args: the class's constructor arguments after the two sizes (e.g. a width).
            key: PRNG key of the initial weights; ``PRNGKey(0)`` by default (the trainers draw their own with
                :meth:`reinit`).
            dtype: floating dtype of the weights; ``None`` for JAX's default.
            **kwargs: further keyword arguments of the constructor.
        """
        key = jax.random.PRNGKey(0) if key is None else key
        return cls(task.observation_size, task.action_size, *args, key=key, dtype=dtype, **kwargs)

    @abc.abstractmethod
    def reinit(self, key: PRNGKeyArray) -> "AbstractPolicy":
        """The same architecture (sizes and dtype) with fresh initial weights.

        Args:
            key: PRNG key of the new weights.
        """

    @property
    def dtype(self) -> jnp.dtype:
        """The floating dtype of the weights."""
        return jax.tree_util.tree_leaves(eqx.filter(self, eqx.is_inexact_array))[0].dtype

    def initial_state(self) -> Float[Array, " hidden_size"]:
        """The zero hidden state, shape ``(hidden_size,)``, in the weights' dtype."""
        return jnp.zeros(self.hidden_size, self.dtype)

    @abc.abstractmethod
    def __call__(
        self,
        obs: Float[ArrayLike, " obs_size"],
        hidden: Float[Array, " hidden_size"],
        reset: Bool[ArrayLike, ""] = False,
    ) -> tuple[Float[Array, " action_size"], Float[Array, " hidden_size"]]:
        """One step of the policy.

        Args:
            obs: the (normalised) observation, shape ``(obs_size,)``.
            hidden: the hidden state carried from the previous step, shape ``(hidden_size,)``.
            reset: scalar; true where an episode starts (a recurrent policy replaces ``hidden`` by zeros first).

        Returns:
            ``(action, hidden)``: the action in ``[-1, 1]``, shape ``(action_size,)`` (dimensionless; the task
            multiplies it by the chain's gear), and the new hidden state.
        """


class AbstractFeedForwardPolicy(AbstractPolicy):
    """A stateless policy: its action is :meth:`deterministic` of the observation alone. As a rollout policy it takes
    and returns an empty hidden state (``hidden_size`` 0), so that rollouts treat every policy alike."""

    @abc.abstractmethod
    def deterministic(self, obs: Float[ArrayLike, " obs_size"]) -> Float[Array, " action_size"]:
        """The action for ``obs``, in ``[-1, 1]``, shape ``(action_size,)``, dimensionless.

        Args:
            obs: the (normalised) observation, shape ``(obs_size,)``.
        """

    def __call__(
        self,
        obs: Float[ArrayLike, " obs_size"],
        hidden: Float[Array, " 0"],
        reset: Bool[ArrayLike, ""] = False,
    ) -> tuple[Float[Array, " action_size"], Float[Array, " 0"]]:
        """One step of the policy (:meth:`AbstractPolicy.__call__`): ``(deterministic(obs), hidden)``, the empty
        hidden state (shape ``(0,)``) unchanged and ``reset`` unused."""
        return self.deterministic(obs), hidden
