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
from typing import ClassVar, NamedTuple
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec
from jaxtyping import Array, ArrayLike, Float, Int, PRNGKeyArray

from lagrange.tasks import AbstractTask
from lagrange.compile import compiler_options
from optim.base import Trainer
from optim.bptt import apg_steps, flatten_policy, mean_return_loss
from optim.curriculum import Curriculum, check_curriculum
from optim.devices import jit_replicated, population_mesh
from optim.episode import episode
from optim.inner_apg import InnerAPGConfig
from optim.validate import check_bool, check_int, check_positive
from policies import BraxNormalizer, Normalizer

__all__ = ["CEAPGConfig", "CEState", "make_trainer", "training_tasks"]


@dataclasses.dataclass(frozen=True)
class CEAPGConfig(InnerAPGConfig):
    """CE-APG settings. The defaults are the authors' protocol, ``authors_normalizer`` aside (``CEAPGConfig.paper()``:
    4.8e6 env steps per iteration of 500-step episodes, about 1e9 in all); ``CEAPGConfig.laptop(name)`` is this
    project's cheaper one for a paper task. The task and the policy are not settings: they are passed to
    :func:`optim.train` (the paper's policy is ``policies.GRUPolicy`` of width 16, 32 for the double cartpole).

    The fields of the APG inner loop are :class:`optim.inner_apg.InnerAPGConfig`'s (``iterations`` counts CE
    iterations here, ``apg_steps`` the Adam steps of every candidate in each, from a fresh Adam state); the five
    curriculum fields make the :class:`optim.curriculum.Curriculum` ``config.curriculum`` (they stay flat fields, so
    that the JSON a checkpoint or a result records and the benchmarks' ``--set warmup_horizons=300,400`` keep their
    form).

    Attributes:
        num_candidates (int): candidates sampled per iteration, >= 1 (paper: 24).
        num_elites (int): candidates whose post-APG parameters refit the Gaussian, 1 <= num_elites <=
            num_candidates (paper: 8).
        init_std (float): initial per-parameter standard deviation, >= 0; the mean starts at all zeros (paper: 0.05).
        upright_starts (float): :attr:`optim.curriculum.Curriculum.upright_starts` (paper: 0).
        train_noise (float | None): :attr:`optim.curriculum.Curriculum.train_noise` (paper: None).
        warmup_horizons (tuple[int, ...]): :attr:`optim.curriculum.Curriculum.warmup_horizons` (paper: none);
            needs ``apg_steps >= 1``, and ``iterations`` must cover the warm-up.
        warmup_iterations (int): :attr:`optim.curriculum.Curriculum.warmup_iterations`.
        warmup_upright (float): :attr:`optim.curriculum.Curriculum.warmup_upright`.
        authors_normalizer (bool): the authors' normaliser protocol (paper: True; ``paper()`` sets it, the field's
            default is False): ONE :class:`policies.BraxNormalizer` (Brax v1's, from its prior ``m2 = 1``) shared by
            all candidates, updated once per iteration from one episode of the CE mean (started from candidate 0's
            key, with the normaliser of the previous iteration) before the candidates run, and frozen through every
            APG step and the fitness; CEM never updates it. False (this project's laptop protocol): a
            :class:`policies.Normalizer` per candidate that absorbs every APG batch, the elites' statistics averaged
            into the next iteration's. Needs ``normalize=True``.
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
        check_curriculum(c, self)
        check_bool(c, "authors_normalizer", self.authors_normalizer)
        if self.authors_normalizer and not self.normalize:
            raise ValueError(f"{c}.authors_normalizer needs normalize=True (it is a normaliser protocol)")
        if self.warmup_horizons and self.apg_steps == 0:
            raise ValueError(f"{c}.warmup_horizons needs apg_steps >= 1 (the curriculum shapes the APG gradient), "
                             f"got apg_steps=0")
        if self.curriculum.warmup_length > self.iterations:
            raise ValueError(f"{c}.iterations ({self.iterations}) must cover the warm-up: len(warmup_horizons) * "
                             f"warmup_iterations = {self.curriculum.warmup_length}")

    @classmethod
    def paper(cls, **overrides) -> "CEAPGConfig":
        """The authors' protocol: 24 candidates x 100 APG steps x 4 episodes per iteration, 200 iterations, their
        normaliser protocol; ``overrides`` are fields to change."""
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

        Args:
            task: ``"acrobot"``, ``"cartpole"`` or ``"double_cartpole"``.
            **overrides: fields to change.

        Raises:
            ValueError: for another task name, or a field out of range.
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

    @property
    def curriculum(self) -> Curriculum:
        """The five curriculum fields as one :class:`optim.curriculum.Curriculum`."""
        return Curriculum(self.upright_starts, self.train_noise, self.warmup_horizons, self.warmup_iterations,
                          self.warmup_upright)

    def with_iterations(self, iterations: int) -> "CEAPGConfig":
        """The same protocol over another number of CE iterations. The learning-rate schedule spans ``iterations``
        and so compresses by itself; the warm-up compresses in proportion
        (:meth:`optim.curriculum.Curriculum.compressed`).

        Args:
            iterations: the new iteration count, >= 1.
        """
        short = self.curriculum.compressed(self.iterations, iterations)
        return dataclasses.replace(self, iterations=iterations, warmup_horizons=short.warmup_horizons,
                                   warmup_iterations=short.warmup_iterations)

    @property
    def warmup_stages(self) -> int:
        """The number of warm-up stages, ``len(warmup_horizons)``."""
        return self.curriculum.stages

    def stage(self, iteration: Int[ArrayLike, ""]) -> Int[Array, ""]:
        """The curriculum stage (:meth:`optim.curriculum.Curriculum.stage`).

        Args:
            iteration: the 0-based iteration, an int or a traced integer.
        """
        return self.curriculum.stage(iteration)

    def training_horizon(self, iteration: int, horizon: int) -> int:
        """The episode length candidates train on (:meth:`optim.curriculum.Curriculum.training_horizon`).

        Args:
            iteration: the 0-based iteration.
            horizon: the task's episode length in control steps.
        """
        return self.curriculum.training_horizon(iteration, horizon)

    def env_steps_per_iteration(self, horizon: int, iteration: int | None = None) -> int:
        """Simulated control steps of one iteration.

        Args:
            horizon: the task's episode length in control steps.
            iteration: the 0-based iteration, whose warm-up stage may shorten the episodes; None: the task's horizon.
        """
        h = horizon if iteration is None else self.training_horizon(iteration, horizon)
        return self.num_candidates * max(self.apg_steps, 1) * self.episodes * h

    def total_env_steps(self, horizon: int) -> int:
        """Simulated control steps of the whole run.

        Args:
            horizon: the task's episode length in control steps.
        """
        return sum(self.env_steps_per_iteration(horizon, i) for i in range(self.iterations))

    def make_trainer(self, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
        """:func:`optim.ce_apg.make_trainer` of this config (the arguments are documented there)."""
        return make_trainer(self, task, policy, objective=objective)


class CEState(NamedTuple):
    """CE-APG's training state (``P`` flat policy parameters).

    Attributes:
        mean (Float[Array, "P"]): the search distribution's mean.
        std (Float[Array, "P"]): its per-parameter standard deviation.
        normalizer (Normalizer | BraxNormalizer | None): its observation normaliser (None without normalisation).
        best (Float[Array, "P"]): the best candidate of the last iteration.
        best_normalizer (Normalizer | BraxNormalizer | None): that candidate's normaliser.
        key (PRNGKeyArray): the run's raw key; iteration ``i`` draws from ``fold_in(key, i)``.
        iteration (Int[Array, ""]): iterations done, int32.
    """

    mean: Float[Array, " P"]
    std: Float[Array, " P"]
    normalizer: Normalizer | None
    best: Float[Array, " P"]
    best_normalizer: Normalizer | None
    key: Array
    iteration: Int[Array, ""]


def training_tasks(config: CEAPGConfig, task: AbstractTask) -> list[AbstractTask]:
    """The tasks candidates train and are scored on, one per curriculum stage
    (:meth:`optim.curriculum.Curriculum.tasks` of ``config.curriculum``).

    Args:
        config: the settings (errors name its class).
        task: the task as given.
    """
    return config.curriculum.tasks(task, owner=type(config).__name__)


def make_trainer(config: CEAPGConfig, task: AbstractTask, policy, *, objective: Callable | None = None) -> Trainer:
    """CE-APG on ``task`` over the parameters of ``policy``; ``update`` runs one jitted CE iteration with the
    candidates sharded over ``jax.devices()``.

    Args:
        config: the settings.
        task: the task candidates train on (through ``config.curriculum``) and the trainer evaluates.
        policy: the policy module, its architecture (the search mean starts at zeros, as the authors').
        objective: the loss of an episode batch (default :func:`optim.mean_return_loss`).

    Returns:
        The :class:`optim.Trainer`. Its metrics: ``best_return``, ``elite_return``, ``mean_return`` (of the finite
        candidates), ``nonfinite`` (how many candidates went non-finite) and ``nonfinite_members`` (which: a
        ``(num_candidates,)`` bool mask), ``learning_rate``, ``std``, ``env_steps``, ``training_horizon``.
    """
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
            "nonfinite_members": bad,
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

    return Trainer(init, jit_replicated(update, replicated, compiler_options(task.chain)), policy_of, task, config,
                   ("best_return", "elite_return", "mean_return"))
