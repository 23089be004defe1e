"""The one APG inner step: Adam updates of a flat parameter vector on the gradient of an episode batch's loss,
back-propagated through time. CE-APG's candidates, PAPG's runs and plain APG all call :func:`apg_steps`; a variant
passes its own ``objective`` instead of patching anything."""

from __future__ import annotations

from typing import Any, NamedTuple
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree
from jaxtyping import Array, Bool, Float, PRNGKeyArray

from lagrange.tasks import AbstractTask
from optim.episode import Episode, episode
from optim.grad_clip import clip_grad_norm
from policies import Normalizer

__all__ = ["APGResult", "apg_steps", "mean_return_loss", "flatten_policy"]


def flatten_policy(policy) -> tuple[Float[Array, " P"], Callable[[Array], Any]]:
    """The policy's array leaves as one vector, and the function that rebuilds the module from one.

    Args:
        policy: an equinox module.

    Returns:
        ``(flat, unravel)``: the parameters, shape ``(P,)``, and ``unravel(x) -> module`` for any ``x`` of that shape.
    """
    arrays, static = eqx.partition(policy, eqx.is_array)
    flat, unravel_arrays = ravel_pytree(arrays)

    def unravel(x):
        return eqx.combine(unravel_arrays(x), static)

    return flat, unravel


def mean_return_loss(episodes: Episode) -> Float[Array, ""]:
    """The default objective: minus the mean return of a batch of episodes.

    Args:
        episodes: an :class:`optim.Episode` whose leaves have a leading batch axis.

    Returns:
        ``-mean(episodes.ret)``, a scalar.
    """
    return -jnp.mean(episodes.ret)


class APGResult(NamedTuple):
    """What :func:`apg_steps` returns.

    Attributes:
        params: final parameters ``(P,)``, frozen at the last finite update.
        normalizer: the normaliser after the updates (unchanged when it is frozen or absent).
        returns: minus the objective of each step's batch, before that step's update, ``(steps,)`` (the mean batch
            return for the default objective).
        finite: ``()`` bool: every objective value and gradient stayed finite.
        opt_state: the Adam state after the last update (``optax.scale_by_adam``'s), for a caller that carries it.
        grad_norms: the global 2-norm of each step's gradient, before any clipping, ``(steps,)`` (non-finite where
            the gradient was).
    """

    params: Float[Array, " P"]
    normalizer: Normalizer | None
    returns: Float[Array, " steps"]
    finite: Bool[Array, ""]
    opt_state: Any
    grad_norms: Float[Array, " steps"]


def apg_steps(task: AbstractTask, unravel: Callable[[Array], Any], params: Float[Array, " P"],
              normalizer: Normalizer | None, key: PRNGKeyArray, *, steps: int, episodes: int, learning_rate,
              truncation: int | None = None, objective: Callable[[Episode], Array] = mean_return_loss,
              opt_state=None, update_normalizer: bool = True, max_grad_norm: float | None = None) -> APGResult:
    """``steps`` Adam updates of ``params`` on ``objective`` of ``episodes`` random-start episodes.

    Step ``i`` rolls out ``unravel(params)`` from the keys ``split(fold_in(key, i), episodes)`` (:func:`episode`,
    vmapped), differentiates ``objective(batch)`` through the whole rollout (truncated every ``truncation`` steps if
    given) and takes one Adam step of size ``learning_rate`` (a float or a traced scalar). Adam starts fresh
    (``opt_state=None``, as the CE-APG authors do for every candidate) or from a given ``scale_by_adam`` state. With
    ``update_normalizer`` the normaliser absorbs each batch's observations after its step; otherwise it is frozen.
    If an objective value or gradient goes non-finite, that update and every later one is skipped and ``finite`` is
    false. No gradient clipping by default (as the authors ran it); ``max_grad_norm`` rescales a gradient whose
    global 2-norm exceeds it to that norm before Adam sees it. ``grad_norms`` records each step's norm either way.

    Args:
        task: the task.
        unravel: ``unravel(params) -> policy`` (:func:`flatten_policy`).
        params: the starting parameters, shape ``(P,)``.
        normalizer: the observation normaliser, or None.
        key: PRNG key of the episodes' starts.
        steps: Adam steps, >= 1.
        episodes: random-start episodes per step, >= 1.
        learning_rate: Adam's step size, a float or a traced scalar.
        truncation: truncated-BPTT window in control steps, or None for the whole episode.
        objective: ``objective(episodes) -> loss`` of a batch (default :func:`mean_return_loss`).
        opt_state: an ``optax.scale_by_adam`` state to continue, or None for a fresh one.
        update_normalizer: whether the normaliser absorbs each batch's observations.
        max_grad_norm: the largest global gradient 2-norm let through, > 0, or None.

    Returns:
        An :class:`APGResult`.

    Raises:
        ValueError: for ``max_grad_norm <= 0``, or ``steps`` or ``episodes`` < 1.
    """
    adam = optax.scale_by_adam()

    def loss(p, norm, keys):
        policy = unravel(p)
        eps = jax.vmap(lambda k: episode(task, policy, norm, k, truncation=truncation))(keys)
        return objective(eps), eps.obs

    grad_fn = jax.value_and_grad(loss, has_aux=True)

    def body(carry, i):
        p, opt, norm, ok = carry
        keys = jax.random.split(jax.random.fold_in(key, i), episodes)
        (value, obs), g = grad_fn(p, norm, keys)
        good = ok & jnp.isfinite(value) & jnp.all(jnp.isfinite(g))
        norm_g = jnp.sqrt(jnp.sum(g**2))
        g = jnp.where(good, g, 0.0)
        if max_grad_norm is not None:  # g is zero where it was not finite, and so is the norm it is scaled by
            g, _ = clip_grad_norm(g, max_grad_norm, norm=jnp.where(good, norm_g, 0.0), eps=None)
        upd, opt2 = adam.update(g, opt)
        p2 = p - learning_rate * upd
        keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
        p2, opt2 = keep(p2, p), keep(opt2, opt)
        if norm is not None and update_normalizer:
            norm = keep(norm.update(obs), norm)
        return (p2, opt2, norm, good), (-value, norm_g)

    if max_grad_norm is not None and not max_grad_norm > 0:
        raise ValueError(f"apg_steps: max_grad_norm must be None or > 0, got {max_grad_norm!r}")
    for name, value in (("steps", steps), ("episodes", episodes)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"apg_steps: {name} must be an integer >= 1, got {value!r}")
    opt0 = adam.init(params) if opt_state is None else opt_state
    (p, opt, norm, ok), (returns, grad_norms) = jax.lax.scan(body, (params, opt0, normalizer, jnp.asarray(True)),
                                                             jnp.arange(steps))
    return APGResult(p, norm, returns, ok & jnp.all(jnp.isfinite(returns)), opt, grad_norms)
