"""Cross-entropy analytic policy gradients (CE-APG), as the authors ran it, sharded over devices.

Each iteration samples candidates ``theta_k = mu + sigma * eps_k`` from a diagonal Gaussian over
the flat policy parameters, runs ``apg_steps`` Adam steps (fresh Adam state) from each in
parallel (``vmap``; the candidate axis is sharded over every JAX device), scores each by the mean
of its last ``fitness_window`` batch returns, and refits ``mu`` to the mean of the ``num_elites``
best post-APG parameters and ``sigma = sqrt(mean_elites (mu_old - theta_elite)^2)``. A candidate
whose return or gradient goes non-finite gets fitness ``-inf`` (its parameters are frozen at the
last finite update) and is counted in the metrics.

With ``apg_steps = 0`` the same loop is the plain cross-entropy method (see :mod:`optim.cem`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec

from optim import checkpoint
from optim.apg import (
    InnerAPGConfig,
    Trainer,
    _check_int,
    _check_pos,
    _check_probability,
    apg_steps,
    build_policy,
    build_task,
    episode,
    flatten_policy,
    scan_train,
)
from optim.devices import candidate_mesh, jit_replicated
from policies import Normalizer


@dataclasses.dataclass(frozen=True)
class CEAPGConfig(InnerAPGConfig):
    """CE-APG configuration. ``CEAPGConfig.paper(task)`` is the authors' protocol; the defaults
    are this project's cheaper acrobot protocol (deviations listed below).

    Fields (paper value in brackets):
      task: one of ``lagrange.tasks.TASKS`` ["acrobot"].
      num_candidates: candidates sampled per iteration [24].
      num_elites: candidates whose post-APG parameters refit the Gaussian [8].
      iterations: CE iterations [200].
      apg_steps: Adam steps per candidate per iteration, fresh Adam each time [100].
      episodes: random-start episodes per APG step [4].
      horizon: episode length in control steps [500].
      init_std: initial per-parameter standard deviation; the mean starts at all zeros [0.05].
      lr_start, lr_end: Adam step size, log-linear from ``lr_start`` at iteration 0 to
        ``lr_end`` at iteration ``iterations`` (constant within an iteration) [1e-3, 1e-6].
      fitness_window: fitness = mean of the last ``fitness_window`` batch returns [5].
      policy, width: "gru" with H = 16 (32 for the double cartpole) [gru, 16].
      normalize: running observation normalisation clipped to +-5 [True].
      truncation: truncated-BPTT window, None = whole episode [None].
      trig_observation: observe (sin th, cos th, dth) instead of wrapped angles [False]; the wrapped
        first-link angle jumps by 2 pi at every swing through hanging (see ``lagrange.tasks``).
      bodies: "rods", this library's chains (paper-facts' lengths, thin-rod inertias), or "brax_v1", the bodies the
        authors' Brax v1 configs describe (every inertia 1 kg m^2; ``lagrange.systems.BRAX_V1``) [the authors' runs:
        brax_v1; ``paper()`` keeps "rods", the task every other field here is defined on].
      upright_starts: probability that a *training* episode starts balanced upright instead of
        hanging, a curriculum that shows every candidate the balance it must end in [0]. Fitness
        counts those episodes too; ``Trainer.task`` (what the examples evaluate) keeps the paper's
        hanging start.
      train_noise: half-width of the uniform noise on the angles and velocities at the start of every *training*
        episode (warm-up stages included), None = the task's own (+-0.01) [None]. Wider training starts are a
        robustness knob; ``Trainer.task`` (what the examples and benchmarks evaluate) keeps the task's noise.
      warmup_horizons, warmup_iterations, warmup_upright: a curriculum of training-episode lengths
        [not in the paper; none]. The first ``len(warmup_horizons) * warmup_iterations`` of the ``iterations`` train
        and score candidates on episodes of ``warmup_horizons[0]``, then ``[1]``, ... control steps
        (``warmup_iterations`` each) that start upright with probability ``warmup_upright``; the
        rest use ``horizon`` and ``upright_starts``. The learning-rate schedule runs across all
        iterations. BPTT through 500 steps of an unstable chain does not learn even to balance it
        from upright (``research/balance_horizon.py``); growing the horizon from 100 steps does.

    The field defaults are the paper's numbers (4.8e6 env steps per iteration, about 1e9 in all).
    ``CEAPGConfig.laptop(task)`` is the cheaper protocol the examples and ``benchmarks/paper_tables.py
    --budget laptop`` run (fewer elites, APG steps, episodes and iterations, a larger early learning rate).
    """

    num_candidates: int = 24
    num_elites: int = 8
    init_std: float = 0.05
    upright_starts: float = 0.0
    train_noise: float | None = None
    warmup_horizons: tuple[int, ...] = ()
    warmup_iterations: int = 15
    warmup_upright: float = 1.0

    min_apg_steps: ClassVar[int] = 0  # apg_steps = 0 is the plain cross-entropy method (optim.cem)

    def __post_init__(self):
        super().__post_init__()
        c = type(self).__name__
        _check_int(c, "num_candidates", self.num_candidates, 1)
        _check_int(c, "num_elites", self.num_elites, 1)
        if self.num_elites > self.num_candidates:
            raise ValueError(
                f"{c}.num_elites must be <= num_candidates ({self.num_candidates}), got {self.num_elites}")
        _check_pos(c, "init_std", self.init_std, allow_zero=True)
        _check_probability(c, "upright_starts", self.upright_starts)
        if self.train_noise is not None:
            _check_pos(c, "train_noise", self.train_noise, allow_zero=True)
        if isinstance(self.warmup_horizons, (str, bytes)) or not hasattr(self.warmup_horizons, "__iter__"):
            raise ValueError(f"{c}.warmup_horizons must be a sequence of integers >= 1, got {self.warmup_horizons!r}")
        object.__setattr__(self, "warmup_horizons", tuple(self.warmup_horizons))
        for i, h in enumerate(self.warmup_horizons):
            _check_int(c, f"warmup_horizons[{i}]", h, 1)
        _check_int(c, "warmup_iterations", self.warmup_iterations, 1)
        _check_probability(c, "warmup_upright", self.warmup_upright)
        if self.warmup_horizons and self.apg_steps == 0:
            raise ValueError(f"{c}.warmup_horizons needs apg_steps >= 1 (the curriculum shapes the APG gradient), "
                             f"got apg_steps=0")
        if self.warmup_stages * self.warmup_iterations > self.iterations:
            raise ValueError(f"{c}.iterations ({self.iterations}) must cover the warm-up: len(warmup_horizons) * "
                             f"warmup_iterations = {self.warmup_stages * self.warmup_iterations}")

    @classmethod
    def paper(cls, task: str = "acrobot", **overrides) -> "CEAPGConfig":
        """The authors' protocol for ``task`` (24 x 100 x 4 x 500 env steps per iteration, 200 iterations)."""
        width = 32 if task == "double_cartpole" else 16
        return cls(**{"task": task, "width": width, **overrides})

    @classmethod
    def laptop(cls, task: str = "acrobot", **overrides) -> "CEAPGConfig":
        """This project's protocol cut to two CPU cores: the examples' defaults and ``--budget laptop``.

        Acrobot: 24 candidates, 6 elites (paper 8), 50 APG steps (100) of 2 episodes (4), 150
        iterations (200), learning rate 1e-2 -> 1e-4 (1e-3 -> 1e-6), ``(sin th, cos th, dth)``
        observations (the paper's wrapped angles kept every run we tried at ~350): 1.8e8 env steps.
        Cartpole: 8 elites, 25 APG steps of 2 episodes, 120 iterations, 1e-2 -> 1e-4, initial std 0.15:
        7.2e7 env steps. Double cartpole: 8 elites, 25 APG steps of 2 episodes, 150 iterations, 1e-2 -> 1e-4,
        initial std 0.15, H = 32 (9e7 env steps). Measured results: the docs' "Reproducing the paper".
        """
        if task == "acrobot":
            base = dict(num_elites=6, iterations=150, apg_steps=50, episodes=2, lr_start=1e-2, lr_end=1e-4,
                        trig_observation=True)
        elif task in ("cartpole", "double_cartpole"):
            base = dict(num_elites=8, iterations=120 if task == "cartpole" else 150, apg_steps=25, episodes=2,
                        lr_start=1e-2, lr_end=1e-4, init_std=0.15, width=32 if task == "double_cartpole" else 16)
        else:
            raise ValueError(f"CEAPGConfig.laptop: task must be one of {sorted(('acrobot', 'cartpole', 'double_cartpole'))}"
                             f", got {task!r}")
        return cls(**{"task": task, **base, **overrides})

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

    def training_horizon(self, iteration: int) -> int:
        """Episode length candidates train on at ``iteration`` (0-based): a warm-up horizon, then ``horizon``."""
        return (*self.warmup_horizons, self.horizon)[int(self.stage(iteration))]

    def env_steps_per_iteration(self, iteration: int | None = None) -> int:
        """Simulated steps of one iteration (of iteration ``iteration`` when there is a warm-up)."""
        horizon = self.horizon if iteration is None else self.training_horizon(iteration)
        return self.num_candidates * max(self.apg_steps, 1) * self.episodes * horizon

    def total_env_steps(self) -> int:
        return sum(self.env_steps_per_iteration(i) for i in range(self.iterations))


class CEState(NamedTuple):
    """Search distribution ``mean``/``std`` (P,), its normaliser, the best candidate of the last
    iteration (``best`` (P,) and ``best_normalizer``), the run's raw key and the iteration count."""

    mean: jax.Array
    std: jax.Array
    normalizer: Normalizer | None
    best: jax.Array
    best_normalizer: Normalizer | None
    key: jax.Array
    iteration: jax.Array


def make_trainer(config: CEAPGConfig, task=None) -> Trainer:
    """Init/update pair for the host loop; ``update`` runs one jitted CE iteration."""
    task = build_task(config, task)
    # episodes the candidates train and are scored on, one task per curriculum stage (the warm-up horizons, then
    # the full one with upright_starts), all with train_noise; `task` is what the trainer evaluates
    noisy = task if config.train_noise is None else dataclasses.replace(task, noise=float(config.train_noise))
    train_task = dataclasses.replace(noisy, upright=config.upright_starts) if config.upright_starts else noisy
    stage_tasks = [dataclasses.replace(noisy, horizon=h, upright=config.warmup_upright) for h in config.warmup_horizons]
    stage_tasks.append(train_task)
    stage_horizons = jnp.asarray([t.horizon for t in stage_tasks], jnp.float32)
    stage_steps = jnp.asarray([config.env_steps_per_iteration(i * config.warmup_iterations)
                               for i in range(len(stage_tasks))], jnp.float32)
    template = build_policy(config, task, jax.random.PRNGKey(0))
    flat0, unravel = flatten_policy(template)
    P = flat0.size
    mesh = candidate_mesh(config.num_candidates)
    ndev = len(mesh.devices)
    K = config.num_candidates
    Kpad = -(-K // ndev) * ndev  # pad the candidate axis to a multiple of the device count
    shard = NamedSharding(mesh, PartitionSpec("candidates"))
    replicated = NamedSharding(mesh, PartitionSpec())

    def init(key) -> CEState:
        mean = jnp.zeros(P, flat0.dtype)
        std = jnp.full(P, config.init_std, flat0.dtype)
        norm = Normalizer.create(task.observation_size, dtype=flat0.dtype) if config.normalize else None
        return CEState(mean, std, norm, mean, norm, jnp.asarray(key), jnp.asarray(0, jnp.int32))

    def candidate(stage_task, theta, k, norm, lr):
        if config.apg_steps == 0:
            policy = unravel(theta)
            eps = jax.vmap(lambda kk: episode(stage_task, policy, norm, kk))(jax.random.split(k, config.episodes))
            fit = jnp.mean(eps.ret)
            if norm is not None:
                norm = norm.update(eps.obs)
            return theta, norm, jnp.where(jnp.isfinite(fit), fit, -jnp.inf), ~jnp.isfinite(fit), fit
        res = apg_steps(stage_task, unravel, theta, norm, k, steps=config.apg_steps, episodes=config.episodes,
                        learning_rate=lr, truncation=config.truncation)
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
        thetas = jax.lax.with_sharding_constraint(thetas, shard)
        keys = jax.lax.with_sharding_constraint(keys, shard)
        stage = config.stage(state.iteration)

        def run_candidate(theta, k, norm, lr):
            return jax.lax.switch(stage, stage_candidates, theta, k, norm, lr)

        params, norms, fitness, bad, mean_ret = jax.vmap(run_candidate, in_axes=(0, 0, None, None))(
            thetas, keys, state.normalizer, lr)
        params, fitness, bad, mean_ret = params[:K], fitness[:K], bad[:K], mean_ret[:K]
        params = jax.lax.with_sharding_constraint(params, replicated)
        norms = jax.tree_util.tree_map(lambda x: x[:K], norms)
        order = jnp.argsort(-fitness)
        elite = order[: config.num_elites]
        new_mean = jnp.mean(params[elite], axis=0)
        new_std = jnp.sqrt(jnp.mean((state.mean - params[elite]) ** 2, axis=0))
        pick = lambda i: jax.tree_util.tree_map(lambda x: x[i], norms)
        if norms is not None:
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

    def policy(state: CEState, which: str = "best"):
        """``(policy, normalizer)`` for the best candidate of the last iteration, or the CE ``"mean"``."""
        if which == "mean":
            return unravel(state.mean), state.normalizer
        return unravel(state.best), state.best_normalizer

    return Trainer(init, jit_replicated(update, replicated), policy, task, config)


def make_train(config: CEAPGConfig, task=None):
    """``train(key) -> (final CEState, per-iteration metrics)``: the whole run as one jittable function."""
    return scan_train(make_trainer(config, task), config.iterations)


def load_checkpoint(path, task=None) -> tuple[Trainer, CEState]:
    """``(trainer, state)`` from a CE-APG checkpoint, its config read from the file's header (no config needed).

    ``task`` is required for a ``task="custom"`` config, as for :func:`make_trainer`. Raises
    :class:`optim.checkpoint.CheckpointError` for a checkpoint of another algorithm or a corrupt one."""
    saved = dict(checkpoint.read_header(path)["config"])
    algorithm = saved.pop("algorithm", None)
    if algorithm != CEAPGConfig.__name__:
        raise checkpoint.CheckpointError(f"{path} is not a CE-APG checkpoint (its config's algorithm is {algorithm!r})")
    names = {f.name for f in dataclasses.fields(CEAPGConfig)}
    unknown = sorted(set(saved) - names)
    if unknown:
        raise checkpoint.CheckpointError(f"{path} has config fields this CEAPGConfig does not know: {unknown}")
    config = CEAPGConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in saved.items()})
    trainer = make_trainer(config, task)
    state, _ = checkpoint.load(path, trainer.init(jax.random.PRNGKey(0)))
    return trainer, state
