"""What the research scripts' CE-APG experiments share, on the public ``optim`` API.

- :func:`laptop_task` and :func:`laptop_policy`: the paper task and the GRU that ``CEAPGConfig.laptop(name)`` trained
  before the task and the policy left the configs (issue 30): the acrobot with ``(sin, cos)`` observations, GRU width
  16 (32 for the double cartpole).
- :func:`gradient_only`: an APG ``objective`` (:func:`optim.apg_steps`) that adds a term to the gradient of minus the
  mean return while its *value*, the return that CE-APG's fitness averages, stays the batch return.
- :func:`ce_apg_with_fitness`: CE-APG as ``CEAPGConfig.make_trainer`` runs it on one device, with each candidate's
  fitness computed by a function of its post-APG parameters (for a fitness that is not the APG batch returns).
- :func:`iterate`: ``iterations`` of a trainer from a given state (one the script has edited after ``trainer.init``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp

from benchmarks._cli import paper_task
from optim import CEAPGConfig, Trainer, apg_steps, flatten_policy
from optim.ce_apg import CEState, training_tasks
from policies import GRUPolicy, Normalizer

WIDTH = {"acrobot": 16, "cartpole": 16, "double_cartpole": 32}  # the paper's GRU width per task


def laptop_task(name: str, bodies: str = "rods", **options):
    """The paper task ``name`` on ``bodies`` as the laptop protocol trains it: the acrobot observes ``(sin th, cos th,
    dth)`` (``trig=True``); ``options`` are further task fields (``horizon``, ``upright``, ...)."""
    if name == "acrobot":
        options = {"trig": True, **options}
    return paper_task(name, bodies, **options)


def laptop_policy(name: str, task) -> GRUPolicy:
    """The paper's GRU for the task ``name`` (width 16, 32 for the double cartpole), sized for ``task``."""
    return GRUPolicy.for_task(task, WIDTH[name])


def gradient_only(term: Callable) -> Callable:
    """``objective(episodes)`` whose gradient is that of ``-mean return + term(episodes)`` and whose value is
    ``-mean return`` exactly: ``term - stop_gradient(term)`` is 0 in the forward pass (NaN where the term is not
    finite, which skips that update as a non-finite loss would). So the returns :func:`optim.apg_steps` reports, which
    CE-APG's fitness averages, stay the batch returns, as the research scripts' APG loop before issue 30 reported
    them beside a loss with the extra term."""

    def objective(episodes):
        extra = term(episodes)
        return -jnp.mean(episodes.ret) + (extra - jax.lax.stop_gradient(extra))

    return objective


def ce_apg_with_fitness(config: CEAPGConfig, task, policy, *, fitness: Callable) -> Trainer:
    """CE-APG with the candidates' fitness replaced: ``fitness(stage_task, unravel, result, key) -> scalar`` of a
    candidate's :class:`optim.APGResult` (its post-APG parameters and normaliser) and its key.

    Everything else is ``config.make_trainer(task, policy)``'s iteration (the same draws of candidates and keys, the
    curriculum stages of :func:`optim.ce_apg.training_tasks`, the elite refit, the per-candidate normalisers averaged
    over the elites) on one device, without the candidate sharding; a candidate whose APG or fitness goes non-finite
    gets fitness ``-inf``. Only the laptop normaliser protocol (``authors_normalizer=False``) and ``apg_steps >= 1``."""
    if config.authors_normalizer or config.apg_steps == 0:
        raise ValueError("ce_apg_with_fitness: needs authors_normalizer=False and apg_steps >= 1")
    stage_tasks = training_tasks(config, task)
    stage_horizons = jnp.asarray([t.horizon for t in stage_tasks], jnp.float32)
    stage_steps = jnp.asarray([config.env_steps_per_iteration(task.horizon, i * config.warmup_iterations)
                               for i in range(len(stage_tasks))], jnp.float32)
    flat0, unravel = flatten_policy(policy)
    P, K = flat0.size, config.num_candidates

    def init(key) -> CEState:
        mean = jnp.zeros(P, flat0.dtype)
        std = jnp.full(P, config.init_std, flat0.dtype)
        norm = Normalizer.create(task.observation_size, dtype=flat0.dtype) if config.normalize else None
        return CEState(mean, std, norm, mean, norm, jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def candidate(stage_task, theta, k, norm, lr):
        res = apg_steps(stage_task, unravel, theta, norm, k, steps=config.apg_steps, episodes=config.episodes,
                        learning_rate=lr, truncation=config.truncation)
        fit = fitness(stage_task, unravel, res, k)
        bad = ~res.finite | ~jnp.isfinite(fit)
        return res.params, res.normalizer, jnp.where(bad, -jnp.inf, fit), bad

    stage_candidates = [functools.partial(candidate, t) for t in stage_tasks]

    def update(state: CEState):
        key = jax.random.fold_in(state.key, state.iteration)
        k_eps, k_run = jax.random.split(key)
        lr = config.learning_rate(state.iteration)
        thetas = state.mean + state.std * jax.random.normal(k_eps, (K, P), state.mean.dtype)
        keys = jax.random.split(k_run, K)
        stage = config.stage(state.iteration)
        params, norms, fit, bad = jax.vmap(
            lambda th, k, norm, lr: jax.lax.switch(stage, stage_candidates, th, k, norm, lr),
            in_axes=(0, 0, None, None))(thetas, keys, state.normalizer, lr)
        order = jnp.argsort(-fit)
        elite = order[: config.num_elites]
        new_mean = jnp.mean(params[elite], axis=0)
        new_std = jnp.sqrt(jnp.mean((state.mean - params[elite]) ** 2, axis=0))
        if norms is not None:
            new_norm = jax.tree_util.tree_map(lambda x: jnp.mean(x[elite], axis=0), norms)
            best_norm = jax.tree_util.tree_map(lambda x: x[order[0]], norms)
        else:
            new_norm = best_norm = None
        finite = jnp.isfinite(fit)
        metrics = {
            "best_return": fit[order[0]],
            "mean_return": jnp.sum(jnp.where(finite, fit, 0.0)) / jnp.maximum(jnp.sum(finite), 1),
            "elite_return": jnp.mean(fit[elite]),
            "nonfinite": jnp.sum(bad),
            "learning_rate": lr,
            "std": jnp.mean(new_std),
            "env_steps": stage_steps[stage],
            "training_horizon": stage_horizons[stage],
        }
        new = CEState(new_mean, new_std, new_norm, params[order[0]], best_norm, state.key, state.iteration + 1)
        return new, metrics

    def policy_of(state: CEState, which: str = "best"):
        if which == "mean":
            return unravel(state.mean), state.normalizer
        if which != "best":
            raise ValueError(f"which must be 'best' or 'mean', got {which!r}")
        return unravel(state.best), state.best_normalizer

    return Trainer(init, jax.jit(update), policy_of, task, config, ("best_return", "elite_return", "mean_return"))


def iterate(trainer: Trainer, state, iterations: int):
    """``(state, history)`` after ``iterations`` of ``trainer.update`` from ``state``: ``history`` one dict of floats
    per iteration (its metrics, ``iteration`` and cumulative ``env_steps``), as :func:`optim.train` records it."""
    history, env_steps = [], 0.0
    for _ in range(iterations):
        state, metrics = trainer.update(state)
        metrics = {k: float(v) for k, v in jax.device_get(metrics).items()}
        env_steps += metrics.pop("env_steps")
        history.append({**metrics, "iteration": int(state.iteration), "env_steps": env_steps})
    return state, history
