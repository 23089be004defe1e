"""The pieces of a SHAC epoch as pure functions: TD(lambda) targets, the target critic's soft update and the
actor's short-horizon loss."""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from policies.actor_critic import Actor, Critic


def td_lambda_targets(rewards, next_values, dones, gamma: float, lam: float):
    """TD(lambda) value targets of one window, truncated at episode ends and at the window's end.

    ``G_t = r_t + gamma V_{t+1}`` where ``done_t``, else ``G_t = r_t + gamma ((1 - lam) V_{t+1} + lam G_{t+1})``: the
    lambda-weighted average of the n-step returns ``(1 - lam) sum_n lam^(n-1) G^(n) + lam^(k-1) G^(k)`` up to the
    next end at k steps.

    Args:
        rewards: the reward of each step, shape ``(T, N)``.
        next_values: the (target) critic's value of the state each step lands in, ``(T, N)``.
        dones: bool ``(T, N)``: an episode ends at step t (the last row is treated as done: the window ends).
        gamma: the discount.
        lam: the TD(lambda) parameter.

    Returns:
        The targets, shape ``(T, N)``.
    """
    dones = jnp.asarray(dones, bool).at[-1].set(True)

    def body(g_next, x):
        r, v, d = x
        g = r + gamma * jnp.where(d, v, (1 - lam) * v + lam * g_next)
        return g, g

    _, g = jax.lax.scan(body, jnp.zeros_like(rewards[-1]), (rewards, next_values, dones), reverse=True)
    return g


def soft_update(target, online, alpha: float):
    """The authors' target critic update, ``alpha target + (1 - alpha) online`` leaf by leaf.

    Args:
        target: the target network (a pytree).
        online: the online network, of the same structure.
        alpha: the weight of the target, in [0, 1].
    """
    return jax.tree_util.tree_map(lambda t, o: alpha * t + (1 - alpha) * o, target, online)


class Window(NamedTuple):
    """What the actor's rollout of ``h`` steps in ``N`` environments leaves for the critic and the logs (all without
    gradient).

    Attributes:
        obs (Float[Array, "h N obs"]): the normalised observations at the start of each step.
        rewards (Float[Array, "h N"]): each step's reward.
        dones (Bool[Array, "h N"]): an episode ended at this step.
        next_values (Float[Array, "h N"]): the target critic's value of the state each step lands in (before a
            reset).
        raw_obs (Float[Array, "h+1 N obs"]): the raw observations, for the running statistics.
        env_state (TaskState): the states after the window (after resets), ``(N, n)`` each.
        progress (Int[Array, "N"]): control steps into each current episode.
        ep_return (Float[Array, "N"]): each current episode's undiscounted return so far.
        finished_return (Float[Array, ""]): the summed returns of the episodes that ended in the window.
        finished (Int[Array, ""]): how many ended.
    """

    obs: jax.Array
    rewards: jax.Array
    dones: jax.Array
    next_values: jax.Array
    raw_obs: jax.Array
    env_state: Any
    progress: jax.Array
    ep_return: jax.Array
    finished_return: jax.Array
    finished: jax.Array


def actor_loss(actor: Actor, target_critic: Critic, normalizer, task, env_state, progress, ep_return, key, *,
               short_horizon: int, horizon: int, gamma: float):
    """The SHAC actor loss of one window and its :class:`Window` (``has_aux`` style).

    Episodes that reach ``horizon`` inside the window are bootstrapped with the target critic's value of their last
    state and reset, the gradient cut; episodes that end early (``task.terminated``, a hopper that fell) are worth 0
    after their last reward, as is a state whose observation is not finite (the authors' guard), and reset too.

    Args:
        actor: the actor whose samples act.
        target_critic: the target critic, or None: every window's end and episode end is worth 0 (BPTT).
        normalizer: the observation normaliser (frozen over the window), or None.
        task: the task.
        env_state: the ``N`` environments' states (a batched TaskState), cut from the graph at the window's start.
        progress: control steps into each episode, ``(N,)``.
        ep_return: each episode's return so far, ``(N,)``.
        key: PRNG key of the actions' noise and the resets.
        short_horizon: the window's steps ``h``.
        horizon: the task's episode length.
        gamma: the discount.

    Returns:
        ``(loss, window)``.
    """
    n = progress.shape[0]
    env_state = jax.lax.stop_gradient(env_state)
    norm = (lambda o: o) if normalizer is None else normalizer
    observe = jax.vmap(task.observe)
    obs0 = observe(env_state)
    dtype = obs0.dtype
    k_act, k_reset = jax.random.split(key)

    def body(carry, i):
        s, prog, rew_acc, disc, ep_ret, loss, fin_ret, fin = carry
        o = norm(observe(s))
        keys = jax.random.split(jax.random.fold_in(k_act, i), n)
        a = jax.vmap(actor.sample)(o, keys)
        s2 = jax.vmap(task.step)(s, a)
        r = jax.vmap(task.reward)(s, a, s2)
        prog = prog + 1
        done = prog >= horizon
        o2 = observe(s2)
        v = jnp.zeros(n, dtype) if target_critic is None else jax.vmap(target_critic)(norm(o2))
        if task.ends_early:
            ended = jax.vmap(task.terminated)(s2)
            # an episode that ended early is worth nothing after; one cut by the time limit is bootstrapped
            done = done | ended
            v = jnp.where(ended | ~jnp.all(jnp.isfinite(o2), axis=-1), jnp.zeros_like(v), v)
        rew_acc = rew_acc + disc * r
        term = -rew_acc - gamma * disc * v
        closes = done | (i == short_horizon - 1)
        loss = loss + jnp.sum(jnp.where(closes, term, 0.0))
        disc = jnp.where(done, 1.0, disc * gamma)
        rew_acc = jnp.where(done, 0.0, rew_acc)
        r_sg = jax.lax.stop_gradient(r)
        ep_ret = ep_ret + r_sg
        fin_ret = fin_ret + jnp.sum(jnp.where(done, ep_ret, 0.0))
        fin = fin + jnp.sum(done, dtype=jnp.int32)
        ep_ret = jnp.where(done, 0.0, ep_ret)
        fresh = jax.lax.stop_gradient(jax.vmap(task.reset)(jax.random.split(jax.random.fold_in(k_reset, i), n)))
        pick = lambda new, old: jnp.where(done.reshape(done.shape + (1,) * (old.ndim - 1)), new, old)
        s2 = jax.tree_util.tree_map(pick, fresh, s2)
        prog = jnp.where(done, 0, prog)
        out = (jax.lax.stop_gradient(o), r_sg, done, jax.lax.stop_gradient(v),
               jax.lax.stop_gradient(observe(s2)))
        return (s2, prog, rew_acc, disc, ep_ret, loss, fin_ret, fin), out

    zeros = jnp.zeros(n, dtype)
    init = (env_state, progress, zeros, jnp.ones(n, dtype), ep_return, jnp.zeros((), dtype), jnp.zeros((), dtype),
            jnp.zeros((), jnp.int32))
    (s, prog, _, _, ep_ret, loss, fin_ret, fin), (obs, rew, done, nv, raw) = jax.lax.scan(
        body, init, jnp.arange(short_horizon))
    loss = loss / (short_horizon * n)
    raw = jnp.concatenate([jax.lax.stop_gradient(obs0)[None], raw])
    window = Window(obs, rew, done, nv, raw, jax.lax.stop_gradient(s), prog, ep_ret, fin_ret, fin)
    return loss, window
