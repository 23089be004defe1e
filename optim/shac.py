"""Short-horizon actor-critic (SHAC, Xu et al. 2022) as its authors ran it (NVlabs/DiffRL ``algorithms/shac.py``).

One epoch:

1. **Actor.** ``num_envs`` environments continue from where the last window left them, with the
   gradient cut there (``stop_gradient`` of the carried state). For ``short_horizon`` steps the
   stochastic actor acts, ``a = tanh(mu(obs) + exp(log_std) eps)``, and the simulation is
   differentiated through. The loss sums, for every environment at the window's end and at every
   episode end inside the window, minus the discounted reward since the last cut plus ``gamma^k`` times
   the *target* critic's value of the state reached (the gradient flows into that state), and is
   divided by ``short_horizon * num_envs``. An episode that ends inside the window is reset with the
   gradient cut (the reset state is a fresh sample), and its discount restarts at 1. One Adam step
   (betas 0.7, 0.95) with the gradient's global norm clipped to ``actor_grad_norm``.
2. **Critic.** TD(lambda) targets from the window's rewards and the target critic's values, truncated
   at episode ends and at the window's end (:func:`td_lambda_targets`); then ``critic_iterations``
   passes over ``critic_minibatches`` contiguous minibatches (the authors' unshuffled split) of plain
   MSE, each an Adam step with the gradient norm clipped to ``critic_grad_norm``.
3. **Target critic.** ``target = alpha target + (1 - alpha) critic`` (:func:`soft_update`).

Both learning rates fall linearly from their start to ``lr_end`` over ``epochs`` (epoch ``e`` uses
``lr0 + (lr_end - lr0) e / epochs``). Observations are normalised by a running mean/variance; inside
a window the statistics frozen at its start are used, and they are updated with every observation the
window saw (its start and every step). Evaluation is deterministic: ``a = tanh(mu(obs))``.

Actor and critic are MLPs ``[64, 64]`` of Linear -> ELU -> LayerNorm; the actor's output layer is linear
(the mean), its log-std a state-independent vector initialised to -1; the actor's layers keep the
default (PyTorch-style uniform) initialisation and the critic's are orthogonal with gain sqrt(2) and
zero biases, as in the authors' code.

Differences from the authors' code: a non-finite actor or critic gradient skips that update (and is
counted in the metrics) instead of raising; the running-statistics prior is a count of 0 (theirs 1e-4);
the episode return reported during training is that of the stochastic policy, as theirs.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from lagrange.shac_cartpole import shac_cartpole
from lagrange.tasks import TASKS, TaskState, balanced
from policies import Normalizer

__all__ = ["SHACConfig", "SHACState", "Actor", "Critic", "DeterministicPolicy", "make_trainer", "make_train",
           "td_lambda_targets", "soft_update", "actor_loss", "TASKS_SHAC", "make_task", "run"]

TASKS_SHAC: dict[str, Callable] = {**TASKS, "shac_cartpole": shac_cartpole}
"""The tasks SHAC is configured for by name: the CE-APG paper's three and the SHAC authors' cartpole."""


def make_task(name: str):
    if name not in TASKS_SHAC:
        raise ValueError(f"task must be one of {sorted(TASKS_SHAC)}, got {name!r}")
    return TASKS_SHAC[name]()


# ----------------------------------------------------------------------------------------------
# configuration
# ----------------------------------------------------------------------------------------------
def _int(name, v, minimum):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise ValueError(f"SHACConfig.{name} must be an integer >= {minimum}, got {v!r}")


def _real(name, v, lo=None, hi=None, *, lo_open=False, hi_open=False):
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"SHACConfig.{name} must be a real number, got {v!r}") from None
    bad = not np.isfinite(x)
    if lo is not None:
        bad |= x <= lo if lo_open else x < lo
    if hi is not None:
        bad |= x >= hi if hi_open else x > hi
    if bad:
        lb = "" if lo is None else ("(" if lo_open else "[") + f"{lo}"
        ub = "" if hi is None else f"{hi}" + (")" if hi_open else "]")
        raise ValueError(f"SHACConfig.{name} must be a finite number in {lb or '(-inf'}, {ub or 'inf)'}, got {v!r}")


@dataclasses.dataclass(frozen=True)
class SHACConfig:
    """SHAC hyperparameters; the defaults are the authors' cartpole swing-up config
    (``examples/cfg/shac/cartpole_swing_up.yaml`` in NVlabs/DiffRL; their names in brackets).

    task: one of :data:`TASKS_SHAC` ["shac_cartpole"], or "custom" with a task passed to :func:`make_trainer`.
    horizon: episode length in control steps, None = the task's own (240 for shac_cartpole) [episode_length].
    num_envs: parallel environments [num_actors = 64].
    short_horizon: steps per window, h [steps_num = 32].
    epochs: training epochs, one window each [max_epochs = 500].
    gamma: discount [0.99].
    lam: TD(lambda) parameter of the critic targets [lambda = 0.95].
    critic_iterations: passes over the window's data per epoch [16].
    critic_minibatches: contiguous minibatches per pass [num_batch = 4].
    target_alpha: target critic soft update ``target = alpha target + (1 - alpha) critic`` [target_critic_alpha = 0.2].
    actor_lr, critic_lr: initial Adam step sizes [1e-2, 1e-3], decayed linearly to lr_end [1e-5] [lr_schedule = linear].
    adam_b1, adam_b2, adam_eps: Adam's betas and epsilon [betas = (0.7, 0.95); PyTorch eps 1e-8].
    actor_grad_norm, critic_grad_norm: global gradient-norm clip, None = none [grad_norm = 1.0, truncate_grads].
    actor_units, critic_units: hidden widths of the ELU + LayerNorm MLPs [(64, 64), (64, 64)].
    init_log_std: initial state-independent log-std of the actor [actor_logstd_init = -1].
    normalize: running observation mean/std normalisation [obs_rms = True].
    """

    task: str = "shac_cartpole"
    horizon: int | None = None
    num_envs: int = 64
    short_horizon: int = 32
    epochs: int = 500
    gamma: float = 0.99
    lam: float = 0.95
    critic_iterations: int = 16
    critic_minibatches: int = 4
    target_alpha: float = 0.2
    actor_lr: float = 1e-2
    critic_lr: float = 1e-3
    lr_end: float = 1e-5
    adam_b1: float = 0.7
    adam_b2: float = 0.95
    adam_eps: float = 1e-8
    actor_grad_norm: float | None = 1.0
    critic_grad_norm: float | None = 1.0
    actor_units: tuple[int, ...] = (64, 64)
    critic_units: tuple[int, ...] = (64, 64)
    init_log_std: float = -1.0
    normalize: bool = True

    def __post_init__(self):
        if self.task not in TASKS_SHAC and self.task != "custom":
            raise ValueError(f"SHACConfig.task must be one of {sorted(TASKS_SHAC)} (or 'custom' with a task passed "
                             f"to make_trainer), got {self.task!r}")
        if self.horizon is not None:
            _int("horizon", self.horizon, 1)
        _int("num_envs", self.num_envs, 1)
        _int("short_horizon", self.short_horizon, 1)
        _int("epochs", self.epochs, 1)
        _int("critic_iterations", self.critic_iterations, 0)
        _int("critic_minibatches", self.critic_minibatches, 1)
        if self.critic_minibatches > self.num_envs * self.short_horizon:
            raise ValueError(f"SHACConfig.critic_minibatches must be <= num_envs * short_horizon "
                             f"({self.num_envs * self.short_horizon}), got {self.critic_minibatches}")
        _real("gamma", self.gamma, 0, 1, lo_open=True)
        _real("lam", self.lam, 0, 1)
        _real("target_alpha", self.target_alpha, 0, 1)
        for name in ("actor_lr", "critic_lr", "lr_end", "adam_eps"):
            _real(name, getattr(self, name), 0, lo_open=True)
        _real("adam_b1", self.adam_b1, 0, 1, hi_open=True)
        _real("adam_b2", self.adam_b2, 0, 1, hi_open=True)
        for name in ("actor_grad_norm", "critic_grad_norm"):
            if getattr(self, name) is not None:
                _real(name, getattr(self, name), 0, lo_open=True)
        for name in ("actor_units", "critic_units"):
            units = getattr(self, name)
            if not isinstance(units, tuple) or not units or any(
                    isinstance(u, bool) or not isinstance(u, (int, np.integer)) or u < 1 for u in units):
                raise ValueError(f"SHACConfig.{name} must be a non-empty tuple of integers >= 1, got {units!r}")
        _real("init_log_std", self.init_log_std)
        if not isinstance(self.normalize, bool):
            raise ValueError(f"SHACConfig.normalize must be True or False, got {self.normalize!r}")

    def env_steps_per_epoch(self) -> int:
        return self.num_envs * self.short_horizon

    def learning_rates(self, epoch):
        """``(actor_lr, critic_lr)`` of epoch ``epoch`` (0-based): linear from the start value to ``lr_end``."""
        frac = jnp.asarray(epoch) / self.epochs
        return (self.actor_lr + (self.lr_end - self.actor_lr) * frac,
                self.critic_lr + (self.lr_end - self.critic_lr) * frac)


# ----------------------------------------------------------------------------------------------
# networks
# ----------------------------------------------------------------------------------------------
class _MLP(eqx.Module):
    """Linear -> ELU -> LayerNorm for each hidden layer, then a linear output (all non-arrays static)."""

    hidden: tuple
    norms: tuple
    out: eqx.nn.Linear

    def __init__(self, in_size: int, out_size: int, units: tuple[int, ...], *, orthogonal_gain: float | None, key,
                 dtype=None):
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

    def __call__(self, x):
        for lin, norm in zip(self.hidden, self.norms):
            x = norm(jax.nn.elu(lin(x)))
        return self.out(x)


class Actor(eqx.Module):
    """Stochastic tanh-Gaussian actor: ``a = tanh(mu(obs) + exp(log_std) eps)``, ``eps ~ N(0, I)``;
    ``log_std`` (action_size,) does not depend on the state. ``obs`` is the normalised observation."""

    mu: _MLP
    log_std: jax.Array

    def __init__(self, obs_size: int, action_size: int, units=(64, 64), init_log_std: float = -1.0, *, key,
                 dtype=None):
        self.mu = _MLP(obs_size, action_size, tuple(units), orthogonal_gain=None, key=key, dtype=dtype)
        self.log_std = jnp.full(action_size, init_log_std, self.mu.out.weight.dtype)

    def sample(self, obs, key):
        """A reparameterised stochastic action in (-1, 1) (differentiable in the parameters and ``obs``)."""
        mu = self.mu(obs)
        eps = jax.random.normal(key, mu.shape, mu.dtype)
        return jnp.tanh(mu + jnp.exp(self.log_std) * eps)

    def deterministic(self, obs):
        """The evaluation action ``tanh(mu(obs))``."""
        return jnp.tanh(self.mu(obs))


class Critic(eqx.Module):
    """State-value critic ``V(obs)`` (scalar) on normalised observations."""

    net: _MLP

    def __init__(self, obs_size: int, units=(64, 64), *, key, dtype=None):
        self.net = _MLP(obs_size, 1, tuple(units), orthogonal_gain=float(np.sqrt(2.0)), key=key, dtype=dtype)

    def __call__(self, obs):
        return self.net(obs)[0]


class DeterministicPolicy(eqx.Module):
    """The actor's evaluation policy with the rollout interface of :mod:`policies`
    (``policy(obs, hidden, reset) -> (action, hidden)``, a (0,)-sized hidden state)."""

    actor: Actor
    hidden_size: int = eqx.field(static=True, default=0)

    def initial_state(self):
        return jnp.zeros(0, self.actor.log_std.dtype)

    def __call__(self, obs, hidden, reset=False):
        return self.actor.deterministic(obs), hidden


# ----------------------------------------------------------------------------------------------
# the pieces, as pure functions
# ----------------------------------------------------------------------------------------------
def td_lambda_targets(rewards, next_values, dones, gamma: float, lam: float):
    """TD(lambda) value targets of one window, truncated at episode ends and at the window's end.

    ``rewards`` (T, N): reward of step t; ``next_values`` (T, N): the (target) critic's value of the
    state step t lands in; ``dones`` (T, N) bool: an episode ends at step t (the last row is treated
    as done: the window ends). Returns (T, N) targets ``G_t = r_t + gamma V_{t+1}`` where ``done_t``,
    else ``G_t = r_t + gamma ((1 - lam) V_{t+1} + lam G_{t+1})`` -- the lambda-weighted average of the
    n-step returns ``(1 - lam) sum_n lam^(n-1) G^(n) + lam^(k-1) G^(k)`` up to the next end at k steps.
    """
    dones = jnp.asarray(dones, bool).at[-1].set(True)

    def body(g_next, x):
        r, v, d = x
        g = r + gamma * jnp.where(d, v, (1 - lam) * v + lam * g_next)
        return g, g

    _, g = jax.lax.scan(body, jnp.zeros_like(rewards[-1]), (rewards, next_values, dones), reverse=True)
    return g


def soft_update(target, online, alpha: float):
    """``alpha target + (1 - alpha) online`` leaf by leaf (the authors' target critic update)."""
    return jax.tree_util.tree_map(lambda t, o: alpha * t + (1 - alpha) * o, target, online)


def _clip_by_norm(grads, max_norm):
    """PyTorch's ``clip_grad_norm_``: scale by ``min(1, max_norm / (norm + 1e-6))``; returns (grads, norm)."""
    norm = optax.tree.norm(grads)
    if max_norm is None:
        return grads, norm
    coef = jnp.minimum(1.0, max_norm / (norm + 1e-6))
    return jax.tree_util.tree_map(lambda g: g * coef, grads), norm


class Window(NamedTuple):
    """What the actor's rollout leaves for the critic and the logs (all without gradient)."""

    obs: jax.Array  # (h, N, obs) normalised observations at the start of each step
    rewards: jax.Array  # (h, N)
    dones: jax.Array  # (h, N) bool, an episode ended at this step
    next_values: jax.Array  # (h, N) target critic's value of the state each step lands in (pre-reset)
    raw_obs: jax.Array  # (h + 1, N, obs) raw observations for the running statistics
    env_state: Any  # TaskState (N, n) after the window (after resets)
    progress: jax.Array  # (N,) steps into the current episode
    ep_return: jax.Array  # (N,) undiscounted return so far of the current episode
    finished_return: jax.Array  # () sum of the returns of the episodes that ended in the window
    finished: jax.Array  # () how many ended


def actor_loss(actor: Actor, target_critic: Critic, normalizer, task, env_state, progress, ep_return, key, *,
               short_horizon: int, horizon: int, gamma: float):
    """The SHAC actor loss of one window and its :class:`Window` (``has_aux`` style).

    ``env_state`` (batched TaskState, N envs) is cut from the graph at the window's start;
    episodes that reach ``horizon`` inside the window are bootstrapped with the target critic's value
    of their last state and reset, the gradient cut.
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
        v = jax.vmap(target_critic)(norm(observe(s2)))
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


# ----------------------------------------------------------------------------------------------
# trainer
# ----------------------------------------------------------------------------------------------
class SHACState(NamedTuple):
    actor: Actor
    critic: Critic
    target_critic: Critic
    actor_opt: Any
    critic_opt: Any
    normalizer: Normalizer | None
    env_state: TaskState  # (N, n) batched
    progress: jax.Array  # (N,) int32
    ep_return: jax.Array  # (N,)
    key: jax.Array  # the run's key; epoch e draws from fold_in(key, e)
    iteration: jax.Array  # () int32, epochs done


class Trainer(NamedTuple):
    """``init(key) -> state``, ``update(state) -> (state, metrics)`` (one jitted epoch),
    ``policy(state) -> (DeterministicPolicy, normalizer)``, ``evaluate(state, key, episodes) ->
    (returns, balanced)``, the task and the config."""

    init: Callable
    update: Callable
    policy: Callable
    evaluate: Callable
    task: Any
    config: SHACConfig


def _build_task(config: SHACConfig, task):
    if task is None:
        if config.task == "custom":
            raise ValueError("SHACConfig.task is 'custom': pass the task to make_trainer(config, task)")
        task = make_task(config.task)
    if config.horizon is not None and config.horizon != task.horizon:
        task = dataclasses.replace(task, horizon=config.horizon)
    return task


def _normalizer(size, dtype):
    # The authors' RunningMeanStd: (x - mean) / sqrt(var + 1e-5), no clipping.
    return Normalizer(jnp.zeros(size, dtype), jnp.ones(size, dtype), jnp.zeros((), dtype), clip=float("inf"),
                      eps=1e-5)


def make_trainer(config: SHACConfig, task=None) -> Trainer:
    """Init/update pair of SHAC on ``task`` (default: ``config.task``); ``update`` is one jitted epoch."""
    task = _build_task(config, task)
    N, h, T = config.num_envs, config.short_horizon, task.horizon
    adam = optax.scale_by_adam(b1=config.adam_b1, b2=config.adam_b2, eps=config.adam_eps)
    obs_size = task.observation_size
    B = N * h
    mb = -(-B // config.critic_minibatches)  # the authors' batch size: ceil-split into contiguous slices
    bounds = [(i * mb, min((i + 1) * mb, B)) for i in range(config.critic_minibatches) if i * mb < B]
    equal = all(hi - lo == mb for lo, hi in bounds)

    def init(key) -> SHACState:
        k_actor, k_critic, k_env = jax.random.split(jax.random.fold_in(key, 0x5EED), 3)
        dtype = jnp.result_type(task.chain.mass)
        actor = Actor(obs_size, task.action_size, config.actor_units, config.init_log_std, key=k_actor, dtype=dtype)
        critic = Critic(obs_size, config.critic_units, key=k_critic, dtype=dtype)
        env_state = jax.vmap(task.reset)(jax.random.split(k_env, N))
        norm = _normalizer(obs_size, dtype) if config.normalize else None
        return SHACState(actor, critic, critic, adam.init(eqx.filter(actor, eqx.is_array)),
                         adam.init(eqx.filter(critic, eqx.is_array)), norm, env_state,
                         jnp.zeros(N, jnp.int32), jnp.zeros(N, dtype), jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def critic_loss(critic, obs, target):
        return jnp.mean((jax.vmap(critic)(obs) - target) ** 2)

    def update(state: SHACState):
        key = jax.random.fold_in(state.key, state.iteration)
        actor_lr, critic_lr = config.learning_rates(state.iteration)

        # 1. actor: one clipped Adam step on the window's loss
        def loss_fn(actor):
            return actor_loss(actor, state.target_critic, state.normalizer, task, state.env_state, state.progress,
                              state.ep_return, key, short_horizon=h, horizon=T, gamma=config.gamma)

        (loss, win), g = eqx.filter_value_and_grad(loss_fn, has_aux=True)(state.actor)
        g, gnorm = _clip_by_norm(g, config.actor_grad_norm)
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
            cg, _ = _clip_by_norm(cg, config.critic_grad_norm)
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
            config.critic_iterations)
        value_loss = value_losses[-1] if config.critic_iterations else jnp.asarray(jnp.nan, obs_flat.dtype)

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
        broken = ~jnp.all(jnp.isfinite(env_state.q) & jnp.isfinite(env_state.qd), axis=-1)
        fresh = jax.vmap(task.reset)(jax.random.split(jax.random.fold_in(key, 0xBAD), N))
        env_state = jax.tree_util.tree_map(lambda f, o: jnp.where(broken[:, None], f, o), fresh, env_state)
        progress = jnp.where(broken, 0, progress)
        ep_return = jnp.where(broken, 0.0, ep_return)
        metrics["restarted_envs"] = jnp.sum(broken, dtype=jnp.int32)
        new = SHACState(actor, critic, target, actor_opt, critic_opt, norm, env_state, progress,
                        ep_return, state.key, state.iteration + 1)
        return new, metrics

    def policy(state: SHACState):
        return DeterministicPolicy(state.actor), state.normalizer

    def evaluate(state: SHACState, key, episodes: int):
        """Deterministic returns (episodes,) and balanced flags (episodes,) from ``episodes`` random starts."""
        from optim.apg import episode

        pol, norm = policy(state)
        eps = jax.vmap(lambda k: episode(task, pol, norm, k))(jax.random.split(key, episodes))
        return eps.ret, balanced(task, eps.q)

    return Trainer(init, eqx.filter_jit(update), policy, eqx.filter_jit(evaluate), task, config)


def make_train(config: SHACConfig, task=None):
    """``train(key) -> (final SHACState, per-epoch metrics)``: the whole run as one jittable function."""
    trainer = make_trainer(config, task)

    def train(key):
        return jax.lax.scan(lambda s, _: trainer.update(s), trainer.init(key), None, config.epochs)

    return train


# ----------------------------------------------------------------------------------------------
# host loop
# ----------------------------------------------------------------------------------------------
def run(trainer: Trainer, key, *, epochs: int | None = None, eval_every: int = 25, eval_episodes: int = 16,
        eval_key=None, progress: bool = True):
    """Run ``trainer.update`` for ``epochs`` epochs (default: the config's) on the host with a tqdm bar.

    Every ``eval_every`` epochs (and after the last) the deterministic policy is evaluated on
    ``eval_episodes`` random starts drawn from ``eval_key`` (the same starts every time). Returns
    ``(state, history, curve)``: ``history`` has one dict of floats per epoch (cumulative
    ``env_steps`` and ``elapsed`` seconds, evaluation time excluded), ``curve`` one dict per evaluation
    (``epoch``, ``env_steps``, ``elapsed``, ``return``, ``return_std``, ``balanced``).
    """
    import time

    from tqdm.auto import tqdm

    epochs = trainer.config.epochs if epochs is None else epochs
    if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
        raise ValueError(f"epochs must be an integer >= 1, got {epochs!r}")
    if isinstance(eval_every, bool) or not isinstance(eval_every, int) or eval_every < 1:
        raise ValueError(f"eval_every must be an integer >= 1, got {eval_every!r}")
    eval_key = jax.random.PRNGKey(10_000) if eval_key is None else eval_key
    state = trainer.init(key)
    history, curve = [], []
    env_steps, elapsed, last_return = 0.0, 0.0, float("nan")

    def evaluate(epoch):
        rets, bal = jax.device_get(trainer.evaluate(state, eval_key, eval_episodes))
        curve.append({"epoch": epoch, "env_steps": env_steps, "elapsed": elapsed, "return": float(np.mean(rets)),
                      "return_std": float(np.std(rets)), "balanced": float(np.mean(bal))})

    evaluate(0)
    bar = tqdm(total=epochs, disable=not progress, unit="epoch", dynamic_ncols=True)
    for epoch in range(1, epochs + 1):
        t0 = time.perf_counter()
        state, metrics = trainer.update(state)
        metrics = {k: float(v) for k, v in jax.device_get(metrics).items()}
        elapsed += time.perf_counter() - t0
        env_steps += metrics.pop("env_steps")
        if metrics["episodes"] > 0:
            last_return = metrics["episode_return"]
        metrics.update(epoch=epoch, env_steps=env_steps, elapsed=elapsed)
        history.append(metrics)
        if metrics["nonfinite"]:
            bar.write(f"epoch {epoch}: {int(metrics['nonfinite'])} non-finite update(s) skipped")
        if epoch % eval_every == 0 or epoch == epochs:
            evaluate(epoch)
        bar.set_postfix(train_return=f"{last_return:.0f}", eval_return=f"{curve[-1]['return']:.0f}",
                        value_loss=f"{metrics['value_loss']:.3g}", steps=f"{env_steps:.2e}", refresh=False)
        bar.update(1)
    bar.close()
    return state, history, curve
