"""SHAC's trainer: ``make_trainer(config, task, actor) -> Trainer`` (``update`` is one jitted epoch, the environments
sharded over every device)."""

from __future__ import annotations

from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import optax
from jax.sharding import NamedSharding, PartitionSpec

from lagrange.tasks import AbstractTask, TaskState
from lagrange.compile import compiler_options
from optim.base import Trainer
from optim.devices import jit_replicated, population_mesh
from optim.grad_clip import clip_grad_norm
from optim.shac.losses import actor_loss, soft_update, td_lambda_targets
from policies import Normalizer
from policies.actor_critic import Actor, Critic

__all__ = ["SHACState", "make_trainer"]


class SHACState(NamedTuple):
    """SHAC's training state (``N = num_envs`` environments).

    Attributes:
        actor (Actor): the actor.
        critic (Critic): the critic.
        target_critic (Critic): the target critic.
        actor_opt: the actor's Adam state.
        critic_opt: the critic's Adam state.
        normalizer (Normalizer | None): the running observation statistics (None without normalisation).
        env_state (TaskState): the environments' states, ``q`` and ``qd`` of shape ``(N, n)``.
        progress (Int[Array, "N"]): control steps into each environment's episode.
        ep_return (Float[Array, "N"]): each environment's undiscounted return so far.
        key (PRNGKeyArray): the run's key; epoch ``e`` draws from ``fold_in(key, e)``.
        iteration (Int[Array, ""]): epochs done, int32.
    """

    actor: Actor
    critic: Critic
    target_critic: Critic
    actor_opt: Any
    critic_opt: Any
    normalizer: Normalizer | None
    env_state: TaskState
    progress: jax.Array
    ep_return: jax.Array
    key: jax.Array
    iteration: jax.Array


def _normalizer(size, dtype):
    # The authors' RunningMeanStd: (x - mean) / sqrt(var + 1e-5), no clipping.
    return Normalizer(jnp.zeros(size, dtype), jnp.ones(size, dtype), jnp.zeros((), dtype), clip=float("inf"),
                      eps=1e-5)


def make_trainer(config, task: AbstractTask, actor: Actor) -> Trainer:
    """SHAC on ``task``: ``update`` is one jitted epoch; the environments are sharded over the largest number of
    ``jax.devices()`` that divides ``num_envs``.

    Args:
        config: the settings, an :class:`optim.SHACConfig`.
        task: the task to train on, and the one the trainer evaluates.
        actor: a :class:`policies.Actor`, its architecture: the run starts from ``actor.reinit(k)`` for a key ``k``
            drawn from the run's key.

    Returns:
        The :class:`optim.Trainer`; its metrics: ``actor_loss``, ``value_loss``, ``grad_norm``, ``episodes`` and
        ``episode_return`` (of the episodes that ended in the window, NaN if none did), ``mean_reward``, ``actor_lr``,
        ``log_std``, ``nonfinite`` (updates skipped), ``restarted_envs`` and ``nonfinite_envs`` (how many and which
        environments went non-finite and restarted), ``env_steps``.

    Raises:
        TypeError: for a policy that is not an :class:`policies.Actor`.
    """
    if not isinstance(actor, Actor):
        raise TypeError(f"SHAC trains a stochastic policies.Actor, got {type(actor).__name__}")
    N, h, T = config.num_envs, config.short_horizon, task.horizon
    mesh = population_mesh(N, divides=True)
    replicated = NamedSharding(mesh, PartitionSpec())
    adam = optax.scale_by_adam(b1=config.adam_b1, b2=config.adam_b2, eps=config.adam_eps)
    obs_size = task.observation_size
    B = N * h
    mb = -(-B // config.critic_minibatches)  # the authors' batch size: ceil-split into contiguous slices
    bounds = [(i * mb, min((i + 1) * mb, B)) for i in range(config.critic_minibatches) if i * mb < B]
    equal = all(hi - lo == mb for lo, hi in bounds)

    def init(key) -> SHACState:
        k_actor, k_critic, k_env = jax.random.split(jax.random.fold_in(key, 0x5EED), 3)
        dtype = jnp.result_type(task.chain.mass)
        actor0 = actor.reinit(k_actor)
        critic = Critic(obs_size, config.critic_units, key=k_critic, dtype=dtype)
        env_state = jax.vmap(task.reset)(jax.random.split(k_env, N))
        norm = _normalizer(obs_size, dtype) if config.normalize else None
        return SHACState(actor0, critic, critic, adam.init(eqx.filter(actor0, eqx.is_array)),
                         adam.init(eqx.filter(critic, eqx.is_array)), norm, env_state,
                         jnp.zeros(N, jnp.int32), jnp.zeros(N, dtype), jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def critic_loss(critic, obs, target):
        return jnp.mean((jax.vmap(critic)(obs) - target) ** 2)

    def update(state: SHACState):
        key = jax.random.fold_in(state.key, state.iteration)
        actor_lr, critic_lr = config.learning_rates(state.iteration)
        env = lambda x: jax.lax.with_sharding_constraint(x, NamedSharding(mesh, PartitionSpec("population",
                                                                                     *([None] * (x.ndim - 1)))))
        state = state._replace(env_state=jax.tree_util.tree_map(env, state.env_state), progress=env(state.progress),
                               ep_return=env(state.ep_return))

        # 1. actor: one clipped Adam step on the window's loss
        def loss_fn(actor):
            return actor_loss(actor, state.target_critic if config.use_critic else None, state.normalizer, task,
                              state.env_state, state.progress, state.ep_return, key, short_horizon=h, horizon=T,
                              gamma=config.gamma)

        (loss, win), g = eqx.filter_value_and_grad(loss_fn, has_aux=True)(state.actor)
        g, gnorm = clip_grad_norm(g, config.actor_grad_norm)
        actor_ok = jnp.isfinite(loss) & jnp.isfinite(gnorm)
        upd, actor_opt = adam.update(jax.tree_util.tree_map(lambda x: jnp.where(actor_ok, x, 0.0), g),
                                     state.actor_opt)
        new_actor = eqx.apply_updates(state.actor, jax.tree_util.tree_map(lambda u: -actor_lr * u, upd))
        keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(actor_ok, a, b), new, old)
        actor, actor_opt = keep(new_actor, state.actor), keep(actor_opt, state.actor_opt)

        # 2. critic: TD(lambda) targets, critic_iterations x minibatches of clipped Adam on the MSE
        targets = td_lambda_targets(win.rewards, win.next_values, win.dones, config.gamma, config.lam)
        obs_flat = win.obs.reshape(B, obs_size)
        tgt_flat = targets.reshape(B)

        def critic_step(carry, batch):
            critic, opt, bad = carry
            obs_b, tgt_b = batch
            value, cg = eqx.filter_value_and_grad(critic_loss)(critic, obs_b, tgt_b)
            cg = jax.tree_util.tree_map(lambda x: jnp.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0), cg)
            cg, _ = clip_grad_norm(cg, config.critic_grad_norm)
            cu, opt = adam.update(cg, opt)
            critic = eqx.apply_updates(critic, jax.tree_util.tree_map(lambda u: -critic_lr * u, cu))
            return (critic, opt, bad + (~jnp.isfinite(value)).astype(jnp.int32)), value

        def critic_pass(carry, _):
            if equal:  # equal contiguous minibatches: one scanned step
                carry, values = jax.lax.scan(critic_step, carry, (
                    obs_flat.reshape(len(bounds), mb, obs_size), tgt_flat.reshape(len(bounds), mb)))
                return carry, jnp.mean(values)
            values = []
            for lo, hi in bounds:  # static, contiguous, unshuffled slices of unequal sizes
                carry, v = critic_step(carry, (obs_flat[lo:hi], tgt_flat[lo:hi]))
                values.append(v)
            return carry, jnp.mean(jnp.stack(values))

        (critic, critic_opt, critic_bad), value_losses = jax.lax.scan(
            critic_pass, (state.critic, state.critic_opt, jnp.asarray(0, jnp.int32)), None,
            config.critic_iterations if config.use_critic else 0)
        value_loss = (value_losses[-1] if config.critic_iterations and config.use_critic
                      else jnp.asarray(jnp.nan, obs_flat.dtype))

        # 3. target critic, running statistics
        target = soft_update(state.target_critic, critic, config.target_alpha)
        norm = state.normalizer
        if norm is not None:  # skipped for a window that saw a non-finite observation
            obs_ok = jnp.all(jnp.isfinite(win.raw_obs))
            norm = jax.tree_util.tree_map(lambda a, b: jnp.where(obs_ok, a, b), norm.update(win.raw_obs), norm)
        finished = win.finished
        metrics = {
            "actor_loss": loss,
            "value_loss": value_loss,
            "grad_norm": gnorm,
            "episodes": finished.astype(jnp.float32),
            "episode_return": jnp.where(finished > 0, win.finished_return / jnp.maximum(finished, 1), jnp.nan),
            "mean_reward": jnp.mean(win.rewards),
            "actor_lr": actor_lr,
            "log_std": jnp.mean(actor.log_std),
            "nonfinite": (~actor_ok).astype(jnp.int32) + critic_bad,
            "env_steps": jnp.asarray(N * h, jnp.float32),
        }
        # An environment whose state went non-finite restarts (counted), instead of poisoning later windows.
        env_state, progress, ep_return = win.env_state, win.progress, win.ep_return
        broken = ~(jnp.all(jnp.isfinite(env_state.q), axis=-1) & jnp.all(jnp.isfinite(env_state.qd), axis=-1))
        fresh = jax.vmap(task.reset)(jax.random.split(jax.random.fold_in(key, 0xBAD), N))
        env_state = jax.tree_util.tree_map(lambda f, o: jnp.where(broken[:, None], f, o), fresh, env_state)
        progress = jnp.where(broken, 0, progress)
        ep_return = jnp.where(broken, 0.0, ep_return)
        metrics["restarted_envs"] = jnp.sum(broken, dtype=jnp.int32)
        metrics["nonfinite_envs"] = broken
        new = SHACState(actor, critic, target, actor_opt, critic_opt, norm, env_state, progress,
                        ep_return, state.key, state.iteration + 1)
        return new, metrics

    def policy_of(state: SHACState, which: str = "best"):
        """``(actor, normalizer)``: the actor, which acts by ``tanh`` of its mean as a rollout policy."""
        if which != "best":
            raise ValueError(f"SHAC has one policy: which must be 'best', got {which!r}")
        return state.actor, state.normalizer

    return Trainer(init, jit_replicated(update, replicated, compiler_options(task.chain)), policy_of, task, config,
                   ("episode_return", "value_loss"))
