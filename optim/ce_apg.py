"""Cross-entropy analytic policy gradients (CE-APG), as the authors ran it, sharded over devices.

Each iteration samples candidates ``theta_k = mu + sigma * eps_k`` from a diagonal Gaussian over
the flat policy parameters, runs ``apg_steps`` Adam steps (fresh Adam state; :func:`optim.apg_steps`) from each in
parallel (``vmap``; the candidate axis is sharded over every JAX device), scores each by the mean
of its last ``fitness_window`` batch returns, and refits ``mu`` to the mean of the ``num_elites``
best post-APG parameters and ``sigma = sqrt(mean_elites (mu_old - theta_elite)^2)``. A candidate
whose return or gradient goes non-finite gets fitness ``-inf`` (its parameters are frozen at the
last finite update) and is counted in the metrics.

With ``apg_steps = 0`` the same loop is the plain cross-entropy method (:class:`optim.CEMConfig`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable, ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import NamedSharding, PartitionSpec
from jaxtyping import Array, Float, Int, PRNGKeyArray

from lagrange.tasks import AbstractTask
from optim.base import AlgorithmConfig, Trainer
from optim.bptt import apg_steps, flatten_policy, mean_return_loss
from optim.devices import jit_replicated, population_mesh
from optim.episode import episode
from optim.validate import check_bool, check_int, check_positive, check_probability
from policies import BraxNormalizer, Normalizer

__all__ = ["InnerAPGConfig", "CEAPGConfig", "CEState", "make_trainer", "log_linear_lr", "training_tasks"]


def log_linear_lr(iteration, iterations: int, lr_start: float, lr_end: float):
    """The CE-APG authors' schedule: ``lr_start^((T - i) / T) * lr_end^(i / T)`` at iteration ``i`` of ``T``; ``lr_end``
    from ``i = T`` on (a run continued past its planned iterations)."""
    # clamped as an integer, so the float arithmetic below is the same program as before the clamp existed: the
    # chaotic swing-up training turns a one-ulp change of the learning rate into a different run
    frac = jnp.asarray(jnp.minimum(iteration, iterations), jnp.float32) / iterations
    return jnp.exp((1 - frac) * np.log(lr_start) + frac * np.log(lr_end))


@dataclasses.dataclass(frozen=True)
class InnerAPGConfig(AlgorithmConfig):
    """The settings of the APG inner loop every population member runs, shared by :class:`CEAPGConfig` and
    :class:`optim.PAPGConfig` (documented on :class:`CEAPGConfig`): ``iterations`` of ``apg_steps`` Adam steps on
    ``episodes`` episodes at a log-linear learning rate from ``lr_start`` to ``lr_end``, fitness over the last
    ``fitness_window`` batch returns."""

    iterations: int = 200
    apg_steps: int = 100
    episodes: int = 4
    lr_start: float = 1e-3
    lr_end: float = 1e-6
    fitness_window: int = 5
    normalize: bool = True
    truncation: int | None = None
    max_grad_norm: float | None = None

    min_apg_steps: ClassVar[int] = 1  # CE-APG allows 0: the plain cross-entropy method

    def __post_init__(self):
        c = type(self).__name__
        check_int(c, "iterations", self.iterations, 1)
        check_int(c, "apg_steps", self.apg_steps, self.min_apg_steps)
        check_int(c, "episodes", self.episodes, 1)
        check_positive(c, "lr_start", self.lr_start)
        check_positive(c, "lr_end", self.lr_end)
        check_int(c, "fitness_window", self.fitness_window, 1)
        check_bool(c, "normalize", self.normalize)
        if self.truncation is not None:
            check_int(c, "truncation", self.truncation, 1)
        if self.max_grad_norm is not None:
            check_positive(c, "max_grad_norm", self.max_grad_norm)
        if self.apg_steps and self.fitness_window > self.apg_steps:
            raise ValueError(f"{c}.fitness_window must be <= apg_steps ({self.apg_steps}), got {self.fitness_window}")

    def learning_rate(self, iteration):
        """Log-linear from ``lr_start`` at iteration 0 to ``lr_end`` at ``iterations`` (constant within one)."""
        return log_linear_lr(iteration, self.iterations, self.lr_start, self.lr_end)


@dataclasses.dataclass(frozen=True)
class CEAPGConfig(InnerAPGConfig):
    """CE-APG settings. The defaults are the authors' protocol (``CEAPGConfig.paper()``); ``CEAPGConfig.laptop(name)``
    is this project's cheaper one for a paper task. The task and the policy are not settings: they are passed to
    :func:`optim.train` (the paper's policy is ``policies.GRUPolicy`` of width 16, 32 for the double cartpole).

    Fields (paper value in brackets):
      num_candidates: candidates sampled per iteration [24].
      num_elites: candidates whose post-APG parameters refit the Gaussian [8].
      iterations: CE iterations [200].
      apg_steps: Adam steps per candidate per iteration, fresh Adam each time [100].
      episodes: random-start episodes per APG step [4].
      init_std: initial per-parameter standard deviation; the mean starts at all zeros [0.05].
      lr_start, lr_end: Adam step size, log-linear from ``lr_start`` at iteration 0 to
        ``lr_end`` at iteration ``iterations`` (constant within an iteration) [1e-3, 1e-6].
      fitness_window: fitness = mean of the last ``fitness_window`` batch returns [5].
      normalize: running observation normalisation clipped to +-5 [True].
      authors_normalizer: the authors' normaliser protocol [True; ``paper()`` sets it; the field's default is
        False]: ONE :class:`policies.BraxNormalizer` (Brax v1's, from its prior ``m2 = 1``) shared by all
        candidates, updated once per iteration from one episode of the CE mean (started from candidate 0's key, with
        the normaliser of the previous iteration) before the candidates run, and frozen through every APG step and
        the fitness; CEM never updates it. False (this project's laptop protocol): a :class:`policies.Normalizer` per
        candidate that absorbs every APG batch, the elites' statistics averaged into the next iteration's.
      truncation: truncated-BPTT window, None = whole episode [None].
      max_grad_norm: rescale each APG step's gradient to at most this global 2-norm before Adam, None = no
        clipping [None: the authors' ``adaptive_grad_clip(1e9)`` never engages].
      upright_starts: probability that a *training* episode starts balanced upright instead of
        hanging, a curriculum that shows every candidate the balance it must end in [0]. Fitness
        counts those episodes too; ``Trainer.task`` (what is evaluated) keeps the task's own start. Needs a task with
        an ``upright`` field (the swing-ups of :mod:`lagrange.tasks`).
      train_noise: half-width of the uniform noise on the angles and velocities at the start of every *training*
        episode (warm-up stages included), None = the task's own (+-0.01) [None]. Needs a task with a ``noise``
        field; ``Trainer.task`` keeps the task's noise.
      warmup_horizons, warmup_iterations, warmup_upright: a curriculum of training-episode lengths
        [not in the paper; none]. The first ``len(warmup_horizons) * warmup_iterations`` of the ``iterations`` train
        and score candidates on episodes of ``warmup_horizons[0]``, then ``[1]``, ... control steps
        (``warmup_iterations`` each) that start upright with probability ``warmup_upright``; the
        rest use the task's horizon and ``upright_starts``. The learning-rate schedule runs across all iterations.

    The field defaults are the paper's numbers, ``authors_normalizer`` aside (4.8e6 env steps per iteration of
    500-step episodes, about 1e9 in all).
    """

    num_candidates: int = 24
    num_elites: int = 8
    init_std: float = 0.05
    upright_starts: float = 0.0
    train_noise: float | None = None
    warmup_horizons: tuple[int, ...] = ()
    warmup_iterations: int = 15
    warmup_upright: float = 1.0
    authors_normalizer: bool = False

    min_apg_steps: ClassVar[int] = 0  # apg_steps = 0 is the plain cross-entropy method (CEMConfig)

    def __post_init__(self):
        super().__post_init__()
        c = type(self).__name__
        check_int(c, "num_candidates", self.num_candidates, 1)
        check_int(c, "num_elites", self.num_elites, 1)
        if self.num_elites > self.num_candidates:
            raise ValueError(
                f"{c}.num_elites must be <= num_candidates ({self.num_candidates}), got {self.num_elites}")
        check_positive(c, "init_std", self.init_std, allow_zero=True)
        check_probability(c, "upright_starts", self.upright_starts)
        if self.train_noise is not None:
            check_positive(c, "train_noise", self.train_noise, allow_zero=True)
        if isinstance(self.warmup_horizons, (str, bytes)) or not hasattr(self.warmup_horizons, "__iter__"):
            raise ValueError(f"{c}.warmup_horizons must be a sequence of integers >= 1, got {self.warmup_horizons!r}")
        object.__setattr__(self, "warmup_horizons", tuple(self.warmup_horizons))
        for i, h in enumerate(self.warmup_horizons):
            check_int(c, f"warmup_horizons[{i}]", h, 1)
        check_int(c, "warmup_iterations", self.warmup_iterations, 1)
        check_probability(c, "warmup_upright", self.warmup_upright)
        check_bool(c, "authors_normalizer", self.authors_normalizer)
        if self.authors_normalizer and not self.normalize:
            raise ValueError(f"{c}.authors_normalizer needs normalize=True (it is a normaliser protocol)")
        if self.warmup_horizons and self.apg_steps == 0:
            raise ValueError(f"{c}.warmup_horizons needs apg_steps >= 1 (the curriculum shapes the APG gradient), "
                             f"got apg_steps=0")
        if self.warmup_stages * self.warmup_iterations > self.iterations:
            raise ValueError(f"{c}.iterations ({self.iterations}) must cover the warm-up: len(warmup_horizons) * "
                             f"warmup_iterations = {self.warmup_stages * self.warmup_iterations}")

    @classmethod
    def paper(cls, **overrides) -> "CEAPGConfig":
        """The authors' protocol (24 candidates x 100 APG steps x 4 episodes per iteration, 200 iterations, their
        normaliser protocol)."""
        return cls(**{"authors_normalizer": True, **overrides})

    @classmethod
    def laptop(cls, task: str, **overrides) -> "CEAPGConfig":
        """This project's protocol for the paper task called ``task``, cut to two CPU cores: the examples' defaults.

        Acrobot: 24 candidates, 6 elites (paper 8), 50 APG steps (100) of 2 episodes (4), 150
        iterations (200), learning rate 1e-2 -> 1e-4 (1e-3 -> 1e-6), every APG gradient clipped to global norm 1
        (``max_grad_norm=1.0``; the paper clips nothing): 1.8e8 env steps; the examples pair it with
        ``Acrobot(trig=True)`` observations (the paper's wrapped angles kept every run we tried at ~350).
        Cartpole: 8 elites, 25 APG steps of 2 episodes, 120 iterations, 1e-2 -> 1e-4, initial std 0.15:
        7.2e7 env steps. Double cartpole: 8 elites, 25 APG steps of 2 episodes, 150 iterations, 1e-2 -> 1e-4,
        initial std 0.15 (9e7 env steps). Measured results: the docs' "Reproducing the paper".
        """
        if task == "acrobot":
            # the clip keeps a BPTT gradient spike from shrinking the rest of a candidate's Adam steps; on the
            # acrobot it tightens the hold (docs: "Reproducing the paper")
            base = dict(num_elites=6, iterations=150, apg_steps=50, episodes=2, lr_start=1e-2, lr_end=1e-4,
                        max_grad_norm=1.0)
        elif task in ("cartpole", "double_cartpole"):
            base = dict(num_elites=8, iterations=120 if task == "cartpole" else 150, apg_steps=25, episodes=2,
                        lr_start=1e-2, lr_end=1e-4, init_std=0.15)
        else:
            raise ValueError(f"CEAPGConfig.laptop: task must be one of ['acrobot', 'cartpole', 'double_cartpole'], "
                             f"got {task!r}")
        return cls(**{**base, **overrides})

    def with_iterations(self, iterations: int) -> "CEAPGConfig":
        """The same protocol over ``iterations`` CE iterations. The learning-rate schedule spans ``iterations``
        and so compresses by itself; the warm-up compresses in proportion (``warmup_iterations * iterations //
        self.iterations`` per stage), and is dropped when that is less than one iteration."""
        if not self.warmup_horizons:
            return dataclasses.replace(self, iterations=iterations)
        per_stage = self.warmup_iterations * iterations // self.iterations
        if per_stage >= 1:
            return dataclasses.replace(self, iterations=iterations, warmup_iterations=per_stage)
        return dataclasses.replace(self, iterations=iterations, warmup_horizons=())

    @property
    def warmup_stages(self) -> int:
        return len(self.warmup_horizons)

    def stage(self, iteration):
        """Curriculum stage of ``iteration`` (0-based; an int or a traced array): ``i < warmup_stages`` trains on
        ``warmup_horizons[i]``, ``warmup_stages`` on the task itself."""
        return jnp.minimum(iteration // self.warmup_iterations, self.warmup_stages)

    def training_horizon(self, iteration: int, horizon: int) -> int:
        """Episode length candidates train on at ``iteration`` (0-based): a warm-up horizon, then the task's
        ``horizon``."""
        return (*self.warmup_horizons, horizon)[int(self.stage(iteration))]

    def env_steps_per_iteration(self, horizon: int, iteration: int | None = None) -> int:
        """Simulated steps of one iteration on episodes of ``horizon`` steps (of iteration ``iteration`` when there is
        a warm-up)."""
        h = horizon if iteration is None else self.training_horizon(iteration, horizon)
        return self.num_candidates * max(self.apg_steps, 1) * self.episodes * h

    def total_env_steps(self, horizon: int) -> int:
        """Simulated steps of the whole run on a task of ``horizon`` steps."""
        return sum(self.env_steps_per_iteration(horizon, i) for i in range(self.iterations))

    def make_trainer(self, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
        return make_trainer(self, task, policy, objective=objective)


class CEState(NamedTuple):
    """CE-APG's training state.

    Attributes:
        mean, std: the search distribution over the flat parameters, ``(P,)`` each.
        normalizer: its observation normaliser (None without normalisation).
        best: the best candidate of the last iteration ``(P,)``, and ``best_normalizer`` its normaliser.
        key: the run's raw key; iteration ``i`` draws from ``fold_in(key, i)``.
        iteration: iterations done, ``()`` int32.
    """

    mean: Float[Array, " P"]
    std: Float[Array, " P"]
    normalizer: Normalizer | None
    best: Float[Array, " P"]
    best_normalizer: Normalizer | None
    key: Array
    iteration: Int[Array, ""]


def training_tasks(config: CEAPGConfig, task: AbstractTask) -> list[AbstractTask]:
    """The tasks candidates train and are scored on, one per curriculum stage: the warm-up horizons (starting upright
    with probability ``warmup_upright``), then ``task`` itself with ``upright_starts``; all with ``train_noise``."""
    for name, wanted in (("noise", config.train_noise is not None), ("upright", config.upright_starts > 0
                                                                        or bool(config.warmup_horizons))):
        if wanted and not hasattr(task, name):
            raise ValueError(f"{type(config).__name__}: the curriculum needs a task with a {name!r} field (the "
                             f"swing-ups of lagrange.tasks); {type(task).__name__} has none. Leave train_noise=None, "
                             f"upright_starts=0 and warmup_horizons=() for this task")
    noisy = task if config.train_noise is None else dataclasses.replace(task, noise=float(config.train_noise))
    train_task = dataclasses.replace(noisy, upright=config.upright_starts) if config.upright_starts else noisy
    stages = [dataclasses.replace(noisy, horizon=h, upright=config.warmup_upright) for h in config.warmup_horizons]
    return stages + [train_task]


def make_trainer(config: CEAPGConfig, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
    """CE-APG on ``task`` over the parameters of ``policy`` (its architecture; the mean starts at zeros, as the
    authors'); ``update`` runs one jitted CE iteration with the candidates sharded over ``jax.devices()``."""
    objective = mean_return_loss if objective is None else objective
    stage_tasks = training_tasks(config, task)
    stage_horizons = jnp.asarray([t.horizon for t in stage_tasks], jnp.float32)
    stage_steps = jnp.asarray([config.env_steps_per_iteration(task.horizon, i * config.warmup_iterations)
                               for i in range(len(stage_tasks))], jnp.float32)
    flat0, unravel = flatten_policy(policy)
    P = flat0.size
    K = config.num_candidates
    mesh = population_mesh(K)
    ndev = len(mesh.devices)
    Kpad = -(-K // ndev) * ndev  # pad the candidate axis to a multiple of the device count
    shard = NamedSharding(mesh, PartitionSpec("population"))
    replicated = NamedSharding(mesh, PartitionSpec())

    def init(key: PRNGKeyArray) -> CEState:
        mean = jnp.zeros(P, flat0.dtype)
        std = jnp.full(P, config.init_std, flat0.dtype)
        norm = None
        if config.normalize:
            make = BraxNormalizer.create if config.authors_normalizer else Normalizer.create
            norm = make(task.observation_size, dtype=flat0.dtype)
        return CEState(mean, std, norm, mean, norm, jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def candidate(stage_task, theta, k, norm, lr):
        if config.apg_steps == 0:
            pol = unravel(theta)
            eps = jax.vmap(lambda kk: episode(stage_task, pol, norm, kk))(jax.random.split(k, config.episodes))
            fit = -objective(eps)
            if norm is not None and not config.authors_normalizer:
                norm = norm.update(eps.obs)
            return theta, norm, jnp.where(jnp.isfinite(fit), fit, -jnp.inf), ~jnp.isfinite(fit), fit
        res = apg_steps(stage_task, unravel, theta, norm, k, steps=config.apg_steps, episodes=config.episodes,
                        learning_rate=lr, truncation=config.truncation, objective=objective,
                        update_normalizer=not config.authors_normalizer, max_grad_norm=config.max_grad_norm)
        fit = jnp.mean(res.returns[-config.fitness_window:])
        bad = ~res.finite | ~jnp.isfinite(fit)
        return res.params, res.normalizer, jnp.where(bad, -jnp.inf, fit), bad, jnp.mean(res.returns)

    stage_candidates = [functools.partial(candidate, t) for t in stage_tasks]  # one lax.switch branch per stage

    def update(state: CEState):
        key = jax.random.fold_in(state.key, state.iteration)
        k_eps, k_run = jax.random.split(key)
        lr = config.learning_rate(state.iteration)
        eps = jax.random.normal(k_eps, (K, P), state.mean.dtype)
        thetas = state.mean + state.std * eps
        keys = jax.random.split(k_run, K)
        if Kpad > K:  # padding candidates: copies of the mean, dropped before selection
            thetas = jnp.concatenate([thetas, jnp.broadcast_to(state.mean, (Kpad - K, P))])
            keys = jnp.concatenate([keys, jnp.broadcast_to(keys[:1], (Kpad - K,) + keys.shape[1:])])
        norm0 = state.normalizer
        if config.authors_normalizer and config.apg_steps > 0:
            # the authors': one episode of the CE mean (candidate 0's key, last iteration's statistics) updates the
            # one shared normaliser before the candidates run with it frozen
            mean_episode = episode(task, unravel(state.mean), norm0, keys[0])
            norm0 = norm0.update(mean_episode.obs)
        thetas = jax.lax.with_sharding_constraint(thetas, shard)
        keys = jax.lax.with_sharding_constraint(keys, shard)
        stage = config.stage(state.iteration)

        def run_candidate(theta, k, norm, lr):
            return jax.lax.switch(stage, stage_candidates, theta, k, norm, lr)

        params, norms, fitness, bad, mean_ret = jax.vmap(run_candidate, in_axes=(0, 0, None, None))(
            thetas, keys, norm0, lr)
        params, fitness, bad, mean_ret = params[:K], fitness[:K], bad[:K], mean_ret[:K]
        params = jax.lax.with_sharding_constraint(params, replicated)
        norms = jax.tree_util.tree_map(lambda x: x[:K], norms)
        order = jnp.argsort(-fitness)
        elite = order[: config.num_elites]
        new_mean = jnp.mean(params[elite], axis=0)
        new_std = jnp.sqrt(jnp.mean((state.mean - params[elite]) ** 2, axis=0))
        pick = lambda i: jax.tree_util.tree_map(lambda x: x[i], norms)
        if config.authors_normalizer:
            new_norm = best_norm = norm0
        elif norms is not None:
            new_norm = jax.tree_util.tree_map(lambda x: jnp.mean(x[elite], axis=0), norms)
            best_norm = pick(order[0])
        else:
            new_norm = best_norm = None
        finite = jnp.isfinite(fitness)
        metrics = {
            "best_return": fitness[order[0]],
            "mean_return": jnp.sum(jnp.where(finite, fitness, 0.0)) / jnp.maximum(jnp.sum(finite), 1),
            "elite_return": jnp.mean(fitness[elite]),
            "nonfinite": jnp.sum(bad),
            "learning_rate": lr,
            "std": jnp.mean(new_std),
            "env_steps": stage_steps[stage],
            "training_horizon": stage_horizons[stage],
        }
        new = CEState(new_mean, new_std, new_norm, params[order[0]], best_norm, state.key, state.iteration + 1)
        return new, metrics

    def policy_of(state: CEState, which: str = "best"):
        """``(policy, normalizer)`` for the best candidate of the last iteration, or the CE ``"mean"``."""
        if which == "mean":
            return unravel(state.mean), state.normalizer
        if which != "best":
            raise ValueError(f"which must be 'best' or 'mean', got {which!r}")
        return unravel(state.best), state.best_normalizer

    return Trainer(init, jit_replicated(update, replicated), policy_of, task, config,
                   ("best_return", "elite_return", "mean_return"))
