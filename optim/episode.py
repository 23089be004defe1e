"""Rollouts of a policy on a task: one episode, and the deterministic evaluation every algorithm reports."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, PRNGKeyArray

from lagrange.tasks import AbstractTask
from policies import Normalizer

__all__ = ["Episode", "episode", "evaluate"]


class Episode(NamedTuple):
    """One rollout of ``T = task.horizon`` control steps.

    Attributes:
        ret: total return, shape ``()``.
        rewards: reward of each step, shape ``(T,)``.
        obs: the raw (unnormalised) observation the policy saw at each step, shape ``(T, obs_size)``.
        actions: the policy's actions in ``[-1, 1]``, shape ``(T, m)``.
        q: coordinates from the start state on, shape ``(T + 1, n)`` (rad; m for a cart).
        qd: velocities, shape ``(T + 1, n)`` (rad/s; m/s for a cart).
    """

    ret: Float[Array, ""]
    rewards: Float[Array, " T"]
    obs: Float[Array, "T obs"]
    actions: Float[Array, "T m"]
    q: Float[Array, "T1 n"]
    qd: Float[Array, "T1 n"]


def episode(task: AbstractTask, policy, normalizer: Normalizer | None, key: PRNGKeyArray, *,
            truncation: int | None = None) -> Episode:
    """Roll ``policy`` out for ``task.horizon`` steps from ``task.reset(key)``; an episode that ends early
    (``task.terminated``) counts the reward of the transition that ended it and nothing after, its state frozen
    from there.

    The policy sees ``normalizer(obs)`` when a normaliser is given. Its hidden state starts at zeros and is reset at
    step 0. Unbatched: ``jax.vmap`` it over keys.

    Args:
        task: the task.
        policy: a :class:`policies.AbstractPolicy`, ``policy(obs, hidden, reset) -> (action, hidden)``.
        normalizer: the observation normaliser, or None.
        key: PRNG key of the start.
        truncation: cut the gradient through the state every ``truncation`` steps (truncated BPTT), or None.

    Returns:
        The :class:`Episode`.
    """
    s0 = task.reset(key)
    h0 = policy.initial_state()

    def body(carry, t):
        s, h, alive = carry
        obs = task.observe(s)
        x = obs if normalizer is None else normalizer(obs)
        a, h = policy(x, h, t == 0)
        s2 = task.step(s, a)
        r = task.reward(s, a, s2)
        if task.ends_early:  # nothing counts after an early end (a task that cannot traces none of this)
            ended = task.terminated(s2)
            r = jnp.where(alive, r, jnp.zeros_like(r))
            s2 = jax.tree_util.tree_map(lambda new, old: jnp.where(alive, new, old), s2, s)
            alive = alive & ~ended
        if truncation is not None:
            cut = (t + 1) % truncation == 0
            s2 = jax.tree_util.tree_map(lambda v: jnp.where(cut, jax.lax.stop_gradient(v), v), s2)
            h = jnp.where(cut, jax.lax.stop_gradient(h), h)
        return (s2, h, alive), (r, obs, a, s2.q, s2.qd)

    _, (r, obs, a, q, qd) = jax.lax.scan(body, (s0, h0, jnp.ones((), bool)), jnp.arange(task.horizon))
    q = jnp.concatenate([s0.q[None], q])
    qd = jnp.concatenate([s0.qd[None], qd])
    return Episode(jnp.sum(r), r, obs, a, q, qd)


def evaluate(task: AbstractTask, policy, normalizer: Normalizer | None, key: PRNGKeyArray,
             episodes: int) -> tuple[Float[Array, " episodes"], Bool[Array, " episodes"]]:
    """The policy's deterministic returns and balance from random starts.

    Args:
        task: the task.
        policy: a :class:`policies.AbstractPolicy`.
        normalizer: the observation normaliser, or None.
        key: PRNG key of the starts.
        episodes: how many episodes.

    Returns:
        ``(returns, succeeded)``, each of shape ``(episodes,)`` (``task.succeeded``: the poles balanced, for a
        pole task; no early end, for a task that can end early).
    """
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"evaluate: episodes must be an integer >= 1, got {episodes!r}")
    eps = jax.vmap(lambda k: episode(task, policy, normalizer, k))(jax.random.split(key, episodes))
    return eps.ret, task.succeeded(eps.q)
