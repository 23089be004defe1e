"""Analytic policy gradients: back-propagation through whole episodes of a differentiable task.

The building blocks every optimiser here shares live in this module: :func:`episode` (one
rollout of a recurrent policy), :func:`apg_steps` (``steps`` Adam updates of a flat parameter
vector from the gradient of minus the mean return of a batch of random-start episodes), and the
plain APG trainer (:class:`APGConfig`, :func:`make_trainer`, :func:`make_train`).
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any, Callable, ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree

from lagrange.tasks import BODIES, TASKS, Task, make_task
from policies import GRUPolicy, MLPPolicy, Normalizer


# ----------------------------------------------------------------------------------------------
# configuration helpers shared by the optimisers
# ----------------------------------------------------------------------------------------------
def _check_int(cls: str, name: str, value, minimum: int):
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{cls}.{name} must be an integer >= {minimum}, got {value!r}")


def _check_pos(cls: str, name: str, value, *, allow_zero: bool = False):
    try:
        v = float(value)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{cls}.{name} must be a real number, got {value!r}") from err
    if not (v == v and abs(v) != float("inf")) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{cls}.{name} must be a finite number {bound}, got {value!r}")


def _check_probability(cls: str, name: str, value):
    _check_pos(cls, name, value, allow_zero=True)
    if float(value) > 1:
        raise ValueError(f"{cls}.{name} must be a probability in [0, 1], got {value!r}")


def check_common(cfg) -> None:
    """Validate the fields every optimiser config has (task, policy, episode shape)."""
    cls = type(cfg).__name__
    if cfg.task not in TASKS and cfg.task != "custom":
        raise ValueError(f"{cls}.task must be one of {sorted(TASKS)} (or 'custom' with a task passed to "
                         f"make_trainer), got {cfg.task!r}")
    if cfg.policy not in ("gru", "mlp"):
        raise ValueError(f"{cls}.policy must be 'gru' or 'mlp', got {cfg.policy!r}")
    if cfg.bodies not in BODIES:
        raise ValueError(f"{cls}.bodies must be one of {list(BODIES)}, got {cfg.bodies!r}")
    _check_int(cls, "width", cfg.width, 1)
    _check_int(cls, "horizon", cfg.horizon, 1)
    _check_int(cls, "episodes", cfg.episodes, 1)
    if cfg.truncation is not None:
        _check_int(cls, "truncation", cfg.truncation, 1)


def log_linear_lr(iteration, iterations: int, lr_start: float, lr_end: float):
    """The CE-APG authors' schedule: ``lr_start^((T - i) / T) * lr_end^(i / T)`` at iteration ``i`` of ``T``; ``lr_end``
    from ``i = T`` on (a run continued past its planned iterations)."""
    # clamped as an integer, so the float arithmetic below is the same program as before the clamp existed: the
    # chaotic swing-up training turns a one-ulp change of the learning rate into a different run
    frac = jnp.asarray(jnp.minimum(iteration, iterations), jnp.float32) / iterations
    return jnp.exp((1 - frac) * np.log(lr_start) + frac * np.log(lr_end))


@dataclasses.dataclass(frozen=True)
class InnerAPGConfig:
    """The fields of the APG inner loop every population member runs, shared by :class:`optim.ce_apg.CEAPGConfig`
    and :class:`optim.papg.PAPGConfig` (documented there): the task and policy, ``iterations`` of ``apg_steps``
    Adam steps on ``episodes`` episodes of ``horizon`` steps at a log-linear learning rate from ``lr_start`` to
    ``lr_end``, fitness over the last ``fitness_window`` batch returns."""

    task: str = "acrobot"
    iterations: int = 200
    apg_steps: int = 100
    episodes: int = 4
    horizon: int = 500
    lr_start: float = 1e-3
    lr_end: float = 1e-6
    fitness_window: int = 5
    policy: str = "gru"
    width: int = 16
    normalize: bool = True
    truncation: int | None = None
    trig_observation: bool = False
    bodies: str = "rods"

    min_apg_steps: ClassVar[int] = 1  # CE-APG allows 0: the plain cross-entropy method

    def __post_init__(self):
        check_common(self)
        c = type(self).__name__
        _check_int(c, "iterations", self.iterations, 1)
        _check_int(c, "apg_steps", self.apg_steps, self.min_apg_steps)
        _check_pos(c, "lr_start", self.lr_start)
        _check_pos(c, "lr_end", self.lr_end)
        _check_int(c, "fitness_window", self.fitness_window, 1)
        if self.apg_steps and self.fitness_window > self.apg_steps:
            raise ValueError(f"{c}.fitness_window must be <= apg_steps ({self.apg_steps}), got {self.fitness_window}")

    def learning_rate(self, iteration):
        """Log-linear from ``lr_start`` at iteration 0 to ``lr_end`` at ``iterations`` (constant within one)."""
        return log_linear_lr(iteration, self.iterations, self.lr_start, self.lr_end)


def config_to_dict(cfg) -> dict:
    """The config as the JSON a checkpoint header stores (tuples become lists), so it compares equal after a round trip."""
    return json.loads(json.dumps({"algorithm": type(cfg).__name__, **dataclasses.asdict(cfg)}))


def build_task(cfg, task: Task | None = None) -> Task:
    if task is None:
        if cfg.task == "custom":
            raise ValueError(f"{type(cfg).__name__}.task is 'custom': pass the Task to make_trainer(config, task)")
        task = make_task(cfg.task, cfg.bodies)
    elif cfg.bodies != "rods" and task.bodies != cfg.bodies:
        raise ValueError(f"{type(cfg).__name__}.bodies={cfg.bodies!r} names the bodies of a paper task; a task "
                         f"passed to make_trainer brings its own chain (leave bodies='rods', or pass a task "
                         f"make_task built on {cfg.bodies!r}), got a task with bodies={task.bodies!r}")
    if getattr(cfg, "trig_observation", False) and not task.trig:  # a given task too, not silently ignored
        task = dataclasses.replace(task, trig=True)
    if cfg.horizon != task.horizon:
        task = dataclasses.replace(task, horizon=cfg.horizon)
    return task


def build_policy(cfg, task: Task, key):
    if cfg.policy == "gru":
        return GRUPolicy(task.observation_size, task.action_size, cfg.width, key=key)
    return MLPPolicy(task.observation_size, task.action_size, cfg.width, key=key)


class Agent(NamedTuple):
    """A policy as a flat parameter vector, with the function that rebuilds the module."""

    params: jax.Array
    unravel: Callable[[jax.Array], Any]


def flatten_policy(policy) -> tuple[jax.Array, Callable]:
    """``(flat (P,), unravel)``: the policy's array leaves as one vector, and the inverse."""
    arrays, static = eqx.partition(policy, eqx.is_array)
    flat, unravel_arrays = ravel_pytree(arrays)

    def unravel(x):
        return eqx.combine(unravel_arrays(x), static)

    return flat, unravel


# ----------------------------------------------------------------------------------------------
# rollouts
# ----------------------------------------------------------------------------------------------
class Episode(NamedTuple):
    """One rollout: total return (), rewards (T,), observations (T, obs), actions (T, m),
    coordinates q and velocities qd (T+1, n)."""

    ret: jax.Array
    rewards: jax.Array
    obs: jax.Array
    actions: jax.Array
    q: jax.Array
    qd: jax.Array


def episode(task: Task, policy, normalizer: Normalizer | None, key, *, truncation: int | None = None) -> Episode:
    """Roll ``policy`` out for ``task.horizon`` steps from ``task.reset(key)``.

    The hidden state starts at zeros and is reset with ``jnp.where`` at step 0. With
    ``truncation = k`` the gradient through the state is cut every ``k`` steps (truncated BPTT).
    """
    s0 = task.reset(key)
    h0 = policy.initial_state()

    def body(carry, t):
        s, h = carry
        obs = task.observe(s)
        x = obs if normalizer is None else normalizer(obs)
        a, h = policy(x, h, t == 0)
        s2 = task.step(s, a)
        r = task.reward(s, a, s2)
        if truncation is not None:
            cut = (t + 1) % truncation == 0
            s2 = jax.tree_util.tree_map(lambda v: jnp.where(cut, jax.lax.stop_gradient(v), v), s2)
            h = jnp.where(cut, jax.lax.stop_gradient(h), h)
        return (s2, h), (r, obs, a, s2.q, s2.qd)

    _, (r, obs, a, q, qd) = jax.lax.scan(body, (s0, h0), jnp.arange(task.horizon))
    q = jnp.concatenate([s0.q[None], q])
    qd = jnp.concatenate([s0.qd[None], qd])
    return Episode(jnp.sum(r), r, obs, a, q, qd)


def evaluate(task: Task, policy, normalizer, key, episodes: int):
    """Deterministic returns (episodes,) and balanced flags (episodes,) from ``episodes`` random starts."""
    from lagrange.tasks import balanced

    eps = jax.vmap(lambda k: episode(task, policy, normalizer, k))(jax.random.split(key, episodes))
    return eps.ret, balanced(task, eps.q)


# ----------------------------------------------------------------------------------------------
# APG inner loop on a flat parameter vector
# ----------------------------------------------------------------------------------------------
class APGResult(NamedTuple):
    params: jax.Array  # (P,) final parameters (frozen at the last finite update)
    normalizer: Normalizer
    returns: jax.Array  # (steps,) mean batch return before each update
    finite: jax.Array  # () bool: every return and gradient stayed finite


def apg_steps(task: Task, unravel, params, normalizer: Normalizer | None, key, *, steps: int, episodes: int,
              learning_rate, truncation: int | None = None) -> APGResult:
    """``steps`` Adam updates (fresh Adam state) of ``params`` on minus the mean return of
    ``episodes`` random-start episodes, back-propagated through time; step ``i`` uses the key
    ``fold_in(key, i)``. If a return or gradient goes non-finite, that update and every later one
    is skipped and ``finite`` is false. No gradient clipping (as the authors ran it)."""
    adam = optax.scale_by_adam()

    def loss(p, norm, keys):
        policy = unravel(p)
        eps = jax.vmap(lambda k: episode(task, policy, norm, k, truncation=truncation))(keys)
        return -jnp.mean(eps.ret), eps.obs

    grad_fn = jax.value_and_grad(loss, has_aux=True)

    def body(carry, i):
        p, opt, norm, ok = carry
        keys = jax.random.split(jax.random.fold_in(key, i), episodes)
        (value, obs), g = grad_fn(p, norm, keys)
        good = ok & jnp.isfinite(value) & jnp.all(jnp.isfinite(g))
        g = jnp.where(good, g, 0.0)
        upd, opt2 = adam.update(g, opt)
        p2 = p - learning_rate * upd
        keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
        p2, opt2 = keep(p2, p), keep(opt2, opt)
        if norm is not None:
            norm = keep(norm.update(obs), norm)
        return (p2, opt2, norm, good), -value

    init = (params, adam.init(params), normalizer, jnp.asarray(True))
    (p, _, norm, ok), returns = jax.lax.scan(body, init, jnp.arange(steps))
    return APGResult(p, norm, returns, ok & jnp.all(jnp.isfinite(returns)))


# ----------------------------------------------------------------------------------------------
# plain APG trainer
# ----------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class APGConfig:
    """Analytic policy gradient: one policy, Adam on BPTT gradients of whole episodes.

    Fields: ``task`` (one of ``lagrange.tasks.TASKS``); ``iterations`` host-loop iterations of
    ``steps_per_iteration`` Adam steps each; ``episodes`` random-start episodes per step;
    ``learning_rate`` constant Adam step size; ``policy`` "gru" or "mlp" of hidden ``width``;
    ``horizon`` episode length (500 in the paper); ``normalize`` running observation
    normalisation; ``truncation`` optional truncated-BPTT window; ``bodies`` "rods" (this library's) or
    "brax_v1" (the authors' Brax v1 bodies, ``lagrange.tasks.make_task``).
    """

    task: str = "acrobot"
    iterations: int = 20
    steps_per_iteration: int = 50
    episodes: int = 4
    learning_rate: float = 1e-3
    policy: str = "gru"
    width: int = 16
    horizon: int = 500
    normalize: bool = True
    truncation: int | None = None
    trig_observation: bool = False
    bodies: str = "rods"

    def __post_init__(self):
        check_common(self)
        _check_int("APGConfig", "iterations", self.iterations, 1)
        _check_int("APGConfig", "steps_per_iteration", self.steps_per_iteration, 1)
        _check_pos("APGConfig", "learning_rate", self.learning_rate)


class APGState(NamedTuple):
    params: jax.Array
    opt_state: Any
    normalizer: Normalizer | None
    key: jax.Array  # raw uint32 key; iteration keys are fold_in(key, iteration)
    iteration: jax.Array


class Trainer(NamedTuple):
    """Host-loop interface: ``init(key) -> state``, ``update(state) -> (state, metrics)`` (jitted,
    one iteration), ``policy(state) -> (policy module, normalizer)``, and the task/config."""

    init: Callable
    update: Callable
    policy: Callable
    task: Task
    config: Any


def make_trainer(config: APGConfig, task: Task | None = None) -> Trainer:
    task = build_task(config, task)
    template = build_policy(config, task, jax.random.PRNGKey(0))
    _, unravel = flatten_policy(template)
    adam = optax.adam(config.learning_rate)

    def init(key) -> APGState:
        params, _ = flatten_policy(build_policy(config, task, jax.random.fold_in(key, 0x5EED)))
        norm = Normalizer.create(task.observation_size) if config.normalize else None
        return APGState(params, adam.init(params), norm, key, jnp.asarray(0, jnp.int32))

    def update(state: APGState):
        key = jax.random.fold_in(state.key, state.iteration)

        def body(carry, i):
            p, opt, norm = carry
            keys = jax.random.split(jax.random.fold_in(key, i), config.episodes)

            def loss(p):
                policy = unravel(p)
                eps = jax.vmap(lambda k: episode(task, policy, norm, k, truncation=config.truncation))(keys)
                return -jnp.mean(eps.ret), eps.obs

            (value, obs), g = jax.value_and_grad(loss, has_aux=True)(p)
            good = jnp.isfinite(value) & jnp.all(jnp.isfinite(g))
            upd, opt2 = adam.update(jnp.where(good, g, 0.0), opt)
            keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
            p2, opt2 = keep(p + upd, p), keep(opt2, opt)
            if norm is not None:
                norm = keep(norm.update(obs), norm)
            return (p2, opt2, norm), (-value, ~good)

        (p, opt, norm), (rets, bad) = jax.lax.scan(
            body, (state.params, state.opt_state, state.normalizer), jnp.arange(config.steps_per_iteration))
        metrics = {
            "best_return": jnp.max(jnp.where(jnp.isfinite(rets), rets, -jnp.inf)),
            "mean_return": jnp.mean(rets[-min(5, config.steps_per_iteration):]),
            "nonfinite": jnp.sum(bad),
            "env_steps": jnp.asarray(config.steps_per_iteration * config.episodes * config.horizon, jnp.float32),
        }
        return APGState(p, opt, norm, state.key, state.iteration + 1), metrics

    def policy(state: APGState):
        return unravel(state.params), state.normalizer

    return Trainer(init, eqx.filter_jit(update), policy, task, config)


def scan_train(trainer: Trainer, iterations: int):
    """``train(key) -> (final state, stacked metrics)``: ``iterations`` of ``trainer.update`` as one jittable function."""

    def train(key):
        return jax.lax.scan(lambda s, _: trainer.update(s), trainer.init(key), None, iterations)

    return train


def make_train(config: APGConfig, task: Task | None = None):
    """``train(key) -> (final state, stacked metrics)``: the whole run as one jittable function."""
    return scan_train(make_trainer(config, task), config.iterations)
