"""CE-APG (optim/ce_apg.py): the paper's and laptop presets, the warm-up schedule, a stated return on a small problem
(a pendulum swung up and balanced, 850 of 1000) with its checkpoint round trip, the task and policy it is given (their
body set, observation and architecture) kept as given, the candidates' fitness from the objective it is given
(default: the mean return), non-finite candidates, and the training starts (upright, noise, warm-up horizons) kept
apart from the evaluated task."""

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
import optim
from lagrange.planar.lower import lower as planar
from lagrange.tasks import Acrobot, ChainSwingup, DiffRLCartpole
from optim.ce_apg import training_tasks
from policies import BraxNormalizer, GRUPolicy, Normalizer
from tests.helpers import pendulum_swingup, reuse_trainers, states_equal, tiny_mlp


def test_paper_presets():
    c = optim.CEAPGConfig.paper()
    assert (c.num_candidates, c.num_elites, c.iterations, c.apg_steps, c.episodes) == (24, 8, 200, 100, 4)
    assert (c.init_std, c.lr_start, c.lr_end, c.fitness_window, c.truncation) == (0.05, 1e-3, 1e-6, 5, None)
    assert c.authors_normalizer and c == optim.CEAPGConfig(authors_normalizer=True)
    assert optim.CEAPGConfig.paper(iterations=3).iterations == 3
    assert c.env_steps_per_iteration(500) == 4_800_000
    # the paper's schedule: 10^((-3 (T - i) - 6 i) / T)
    for i in (0, 50, 200):
        assert float(c.learning_rate(i)) == pytest.approx(10 ** ((-3 * (200 - i) - 6 * i) / 200), rel=1e-5)
    assert float(c.learning_rate(260)) == pytest.approx(1e-6, rel=1e-5)  # past the planned iterations: lr_end
    m = optim.CEMConfig()
    assert (m.apg_steps, m.iterations, m.fitness_window) == (0, 2000, 1)
    assert m.env_steps_per_iteration(500) == 24 * 1 * 4 * 500  # one batch of episodes per candidate


def test_laptop_presets():
    a = optim.CEAPGConfig.laptop("acrobot")
    assert (a.num_candidates, a.num_elites, a.iterations, a.apg_steps, a.episodes) == (24, 6, 150, 50, 2)
    assert (a.lr_start, a.lr_end, a.init_std, a.authors_normalizer, a.max_grad_norm) == (1e-2, 1e-4, 0.05, False, 1.0)
    assert a.env_steps_per_iteration(500) == 1_200_000
    assert a.warmup_horizons == () and a.total_env_steps(500) == 150 * 1_200_000
    c = optim.CEAPGConfig.laptop("cartpole")
    d = optim.CEAPGConfig.laptop("double_cartpole")
    assert (c.num_elites, c.iterations, c.apg_steps, c.episodes, c.init_std) == (8, 120, 25, 2, 0.15)
    assert (d.iterations, d.lr_start, d.lr_end) == (150, 1e-2, 1e-4)
    assert c.max_grad_norm is None and d.max_grad_norm is None and optim.CEAPGConfig.paper().max_grad_norm is None
    assert optim.CEAPGConfig.laptop("cartpole", iterations=3).iterations == 3


def test_with_iterations_compresses_the_warmup():
    """A shorter run of the same protocol (``--iterations``, ``--quick``): the warm-up keeps its share of the
    iterations, and is dropped once a stage would get less than one."""
    # 20 iterations of 300-step and 20 of 400-step hanging episodes, then 110 of the task's 500
    a = optim.CEAPGConfig.laptop("acrobot", warmup_horizons=(300, 400), warmup_iterations=20, warmup_upright=0.0)
    assert a.total_env_steps(500) == 24 * 50 * 2 * (20 * 300 + 20 * 400 + 110 * 500)
    assert a.with_iterations(150) == a
    q = a.with_iterations(45)
    assert (q.iterations, q.warmup_horizons, q.warmup_iterations) == (45, (300, 400), 6)
    assert [q.training_horizon(i, 500) for i in (0, 5, 6, 11, 12, 44)] == [300, 300, 400, 400, 500, 500]
    assert a.with_iterations(10).warmup_iterations == 1
    one = a.with_iterations(1)
    assert (one.iterations, one.warmup_horizons, one.training_horizon(0, 500)) == (1, (), 500)
    c = optim.CEAPGConfig.laptop("cartpole")  # no warm-up: only the iteration count changes
    assert c.with_iterations(3) == dataclasses.replace(c, iterations=3)


def test_the_task_and_policy_are_taken_as_given():
    """The task (here the authors' Brax v1 bodies with (sin, cos) observations) is trained and evaluated as given,
    and the policy module fixes the parameters the search runs over (the mean starts at zeros, as the authors'); a
    curriculum changes copies of the task, never its bodies or observation, and needs a task with the fields it sets."""
    task = Acrobot.brax_v1(trig=True, horizon=20)
    policy = GRUPolicy.for_task(task, width=4)
    cfg = optim.CEAPGConfig(num_candidates=2, num_elites=1, iterations=1, apg_steps=1, fitness_window=1)
    trainer = cfg.make_trainer(task, policy)
    state = trainer.init(jax.random.PRNGKey(0))
    size = optim.flatten_policy(policy)[0].size
    assert trainer.task is task and task.observation_size == 6
    assert state.mean.shape == state.std.shape == (size,) and not bool(jnp.any(state.mean))
    assert bool(jnp.all(state.std == cfg.init_std)) and state.normalizer.mean.shape == (6,)
    shown, norm = trainer.policy(state, "mean")
    assert type(shown) is GRUPolicy and shown.hidden_size == 6 and norm is state.normalizer
    with pytest.raises(ValueError, match="which must be 'best' or 'mean'"):
        trainer.policy(state, "worst")
    curriculum = dataclasses.replace(cfg, iterations=4, train_noise=0.1, upright_starts=0.3, warmup_horizons=(5, 10),
                                     warmup_iterations=1, warmup_upright=0.5)
    stages = training_tasks(curriculum, task)
    assert [(t.horizon, t.upright, t.noise) for t in stages] == [(5, 0.5, 0.1), (10, 0.5, 0.1), (20, 0.3, 0.1)]
    for t in stages:
        assert type(t) is Acrobot and t.trig and t.bodies == "brax_v1"
        np.testing.assert_array_equal(planar(t.chain).inertia, planar(task.chain).inertia)
    assert curriculum.make_trainer(task, policy).task is task  # evaluation: the task as given
    assert training_tasks(cfg, task) == [task]
    shac_task = DiffRLCartpole.diffrl(horizon=20)
    for field, bad in (("noise", dict(train_noise=0.1)), ("upright", dict(upright_starts=0.5))):
        with pytest.raises(ValueError, match=rf"the curriculum needs a task with a '{field}' field"):
            dataclasses.replace(cfg, **bad).make_trainer(shac_task, GRUPolicy.for_task(shac_task, width=4))


def test_ce_apg_swings_a_pendulum_up(tmp_path):
    """CE-APG swings a torque-limited pendulum (5 N m against 4.9 N m of gravity at horizontal) up from hanging and
    balances it in 10 small iterations (8 x 20 x 2 x 100 env steps each); its checkpoint gives the state back."""
    task = pendulum_swingup(horizon=100)
    policy = GRUPolicy.for_task(task, width=8)
    cfg = optim.CEAPGConfig(num_candidates=8, num_elites=3, iterations=10, apg_steps=20, episodes=2, lr_start=1e-2,
                            lr_end=1e-3, init_std=0.3, truncation=10)
    path = tmp_path / "run.eqx"
    result = optim.train(cfg, task, policy, jax.random.PRNGKey(0), checkpoint=path, seed=0, progress=False)
    ret, bal = optim.evaluate(task, *result.trainer.policy(result.state), jax.random.PRNGKey(7), 32)
    assert float(ret.mean()) > 850  # of 1000; measured 918; a hanging pendulum scores 10 - pi^2 per step (~13)
    assert bool(bal.all())
    assert result.history[-1]["env_steps"] == 10 * 8 * 20 * 2 * 100
    trainer, loaded, head = optim.load(path, task, policy)
    assert trainer.config == cfg and states_equal(loaded, result.state) and head["iteration"] == 10


def last_ten(episodes):
    """A custom objective: minus the mean reward of the last 10 steps."""
    return -jnp.mean(episodes.rewards[:, -10:])


@pytest.mark.parametrize("objective", [None, last_ten], ids=["default", "last_ten"])
def test_candidates_are_scored_by_the_objective(objective):
    """With ``init_std = 0`` every candidate is the zero policy, and with one APG step its fitness is minus the
    objective of its first batch (before the update): the default objective is the mean return
    (``optim.mean_return_loss``), a custom one is used as given, through ``optim.train``."""
    task = pendulum_swingup(horizon=20, noise=0.5)
    policy = tiny_mlp(task)
    cfg = optim.CEAPGConfig(num_candidates=3, num_elites=1, iterations=1, apg_steps=1, episodes=2,
                            fitness_window=1, init_std=0.0)
    key = jax.random.PRNGKey(4)
    result = optim.train(cfg, task, policy, key, progress=False, objective=objective)
    flat, unravel = optim.flatten_policy(policy)
    zero, norm = unravel(jnp.zeros_like(flat)), Normalizer.create(task.observation_size)
    _, k_run = jax.random.split(jax.random.fold_in(key, 0))

    @jax.jit
    def fitness(k):
        keys = jax.random.split(jax.random.fold_in(k, 0), cfg.episodes)
        eps = jax.vmap(lambda kk: optim.episode(task, zero, norm, kk))(keys)
        return -(optim.mean_return_loss if objective is None else objective)(eps)

    fit = np.array([fitness(k) for k in jax.random.split(k_run, cfg.num_candidates)])
    assert len(set(fit.tolist())) == 3  # three batches of starts
    np.testing.assert_allclose(result.history[0]["best_return"], fit.max(), rtol=1e-12)
    np.testing.assert_allclose(result.history[0]["mean_return"], fit.mean(), rtol=1e-12)


def test_authors_normalizer_protocol():
    """``authors_normalizer``: one Brax v1 normaliser, updated once per iteration from one episode of the CE mean
    (candidate 0's key) before the candidates run, and frozen through their APG steps: a candidate's fitness (one
    step: its first batch, before the update) is its return under the updated normaliser, computed here by hand."""
    task = pendulum_swingup(horizon=20, noise=0.5)
    policy = tiny_mlp(task)
    cfg = optim.CEAPGConfig(num_candidates=3, num_elites=1, iterations=1, apg_steps=1, episodes=2,
                            fitness_window=1, authors_normalizer=True)
    trainer = cfg.make_trainer(task, policy)
    key = jax.random.PRNGKey(4)
    init = trainer.init(key)
    assert isinstance(init.normalizer, BraxNormalizer)
    state, metrics = trainer.update(init)
    _, unravel = optim.flatten_policy(policy)
    k_eps, k_run = jax.random.split(jax.random.fold_in(key, 0))
    keys = jax.random.split(k_run, cfg.num_candidates)
    norm = init.normalizer.update(optim.episode(task, unravel(init.mean), init.normalizer, keys[0]).obs)
    for a, b in zip(jax.tree_util.tree_leaves((state.normalizer, state.best_normalizer)),
                    jax.tree_util.tree_leaves((norm, norm))):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)
    assert float(state.normalizer.steps) == 20  # one episode of 20 observations, none from the APG batches
    thetas = init.mean + init.std * jax.random.normal(k_eps, (cfg.num_candidates, init.mean.size), init.mean.dtype)

    @jax.jit
    def fitness(theta, k):
        keys = jax.random.split(jax.random.fold_in(k, 0), cfg.episodes)
        return jnp.mean(jax.vmap(lambda kk: optim.episode(task, unravel(theta), norm, kk).ret)(keys))

    fit = np.array([fitness(t, k) for t, k in zip(thetas, keys)])
    np.testing.assert_allclose(metrics["best_return"], fit.max(), rtol=1e-12)
    np.testing.assert_allclose(metrics["mean_return"], fit.mean(), rtol=1e-12)


def test_nonfinite_candidates_get_minus_infinity_and_do_not_poison(capsys):
    # a gear of 1e300 drives velocities to ~1e298 in one step: their squares overflow to inf, then NaN
    task = ChainSwingup(lg.systems.pendulum(gear=1e300), dt=0.05, horizon=5)
    cfg = optim.CEAPGConfig(num_candidates=4, num_elites=2, iterations=1, apg_steps=2, episodes=1, fitness_window=1,
                            init_std=0.1)
    result = optim.train(cfg, task, tiny_mlp(task), jax.random.PRNGKey(0), progress=False)
    metrics, state = result.history[0], result.state
    assert metrics["nonfinite"] == 4 and metrics["best_return"] == -np.inf
    assert bool(jnp.all(jnp.isfinite(state.mean))) and bool(jnp.all(jnp.isfinite(state.std)))
    assert "iteration 1: 4 update(s) or candidate(s) went non-finite" in capsys.readouterr().out
    assert metrics["nonfinite_members"] == [0, 1, 2, 3]


def test_the_candidates_that_go_nonfinite_are_named(capsys):
    """Which member of the vmapped population went non-finite: the metrics and the message name the candidates
    (here those whose first action is positive, made NaN by the objective), found again by hand from the keys."""
    task = pendulum_swingup(horizon=5)
    policy = tiny_mlp(task)
    cfg = optim.CEAPGConfig(num_candidates=6, num_elites=2, iterations=1, apg_steps=0, episodes=1, fitness_window=1,
                            init_std=1.0, normalize=False)

    def objective(eps):
        return jnp.where(eps.actions[0, 0, 0] > 0, jnp.nan, -jnp.mean(eps.ret))

    key = jax.random.PRNGKey(3)
    result = optim.train(cfg, task, policy, key, objective=objective, progress=False)
    flat, unravel = optim.flatten_policy(policy)
    k_eps, k_run = jax.random.split(jax.random.fold_in(key, 0))
    thetas = 1.0 * jax.random.normal(k_eps, (6, flat.size), flat.dtype)
    first = [float(optim.episode(task, unravel(t), None, jax.random.split(k, 1)[0]).actions[0, 0])
             for t, k in zip(thetas, jax.random.split(k_run, 6))]
    named = result.history[0]["nonfinite_members"]
    assert named == [i for i, a in enumerate(first) if a > 0] and 0 < len(named) < 6
    assert result.history[0]["nonfinite"] == len(named) and bool(jnp.all(jnp.isfinite(result.state.mean)))
    assert f"members (candidates or runs, from 0): {named}" in capsys.readouterr().out


@functools.cache
def _zero_policy_fitness(**curriculum):
    """Best fitness of one iteration of two zero-policy candidates (std 0) scored on 2 episodes without APG steps on
    the 20-step pendulum, and the task the trainer evaluates (cached: the tests below share the plain run)."""
    task = pendulum_swingup(horizon=20)
    cfg = optim.CEAPGConfig(num_candidates=2, num_elites=1, iterations=1, apg_steps=0, episodes=2, init_std=0.0,
                            **curriculum)
    trainer = cfg.make_trainer(task, tiny_mlp(task))
    _, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
    return float(metrics["best_return"]), trainer.task


def test_upright_starts_train_on_balanced_starts_and_evaluate_hanging():
    """``upright_starts`` changes the episodes candidates are scored on, never the task the trainer evaluates.
    With a zero policy a 1 kg pendulum left hanging earns about 10 - pi^2 per step; started upright it earns nearly
    10 per step while it slowly starts to topple."""
    hanging, evaluated = _zero_policy_fitness()
    upright, evaluated_up = _zero_policy_fitness(upright_starts=1.0)
    assert evaluated.upright == evaluated_up.upright == 0  # evaluation keeps the hanging start
    # hanging within ~0.011 rad of straight down (reset noise 0.01 on angle and speed): at most 20 (10 - (pi - 0.011)^2)
    assert hanging <= 20 * (10 - (np.pi - 0.011) ** 2)
    assert upright > 190  # of 200 for a perfect hold; measured 199.9 (a 0.01 rad tilt grows e^3.8t, ~0.4 rad at 1 s)


def test_train_noise_widens_the_training_starts_and_evaluates_the_task():
    """``train_noise`` changes the starts candidates are scored on, never the task the trainer evaluates. With a
    zero policy (no torque) a pendulum started exactly hanging and at rest stays there: 10 - pi^2 per step; the
    task's own +-0.01 is the default (``None``), bit for bit."""
    fitness = {}
    for noise in (None, 0.01, 0.0, 0.5):
        fitness[noise], evaluated = _zero_policy_fitness(**({} if noise is None else {"train_noise": noise}))
        assert evaluated.noise == 0.01  # evaluation keeps the task's noise
    assert fitness[0.01] == fitness[None]
    np.testing.assert_allclose(fitness[0.0], 20 * (10 - np.pi ** 2), rtol=1e-12)
    assert fitness[None] != fitness[0.0]
    # starts up to 0.5 rad and 0.5 rad/s off hanging swing nearer upright: measured 36.2 against 3.3
    assert fitness[0.5] > fitness[None] + 5


def test_warmup_horizons_schedule_the_training_episodes(tmp_path, monkeypatch):
    """The warm-up trains and scores candidates on ``warmup_horizons[i]``-step episodes from upright for
    ``warmup_iterations`` iterations each, then on the full hanging task; env steps follow the stage; a run
    resumed across a stage boundary (its config holds a tuple, stored as JSON) equals an uninterrupted one and
    ``scan_train``. With a zero policy (std 0, a negligible learning rate) a 1 kg pendulum started upright earns
    nearly 10 per step; left hanging about 10 - pi^2. (The resume gets the trainer the first run built for the same
    config, task and policy, ``tests.helpers.reuse_trainers``, instead of compiling its update again.)"""
    reuse_trainers(monkeypatch)
    task = pendulum_swingup(horizon=20)
    policy = tiny_mlp(task)  # zero weights (std 0): no torque, as any zero policy
    cfg = optim.CEAPGConfig(num_candidates=2, num_elites=1, iterations=5, apg_steps=1, episodes=2, fitness_window=1,
                            init_std=0.0, lr_start=1e-12, lr_end=1e-12, warmup_horizons=[4, 8], warmup_iterations=2)
    assert cfg.warmup_horizons == (4, 8) and [cfg.training_horizon(i, 20) for i in range(5)] == [4, 4, 8, 8, 20]
    assert cfg.total_env_steps(20) == 2 * 1 * 2 * (4 + 4 + 8 + 8 + 20)
    key = jax.random.PRNGKey(2)
    full = optim.train(cfg, task, policy, key, checkpoint=tmp_path / "a.eqx", seed=2, progress=False)
    assert full.trainer.task is task  # evaluation: the full hanging task
    hist = full.history
    assert [h["training_horizon"] for h in hist] == [4, 4, 8, 8, 20]
    steps = [h["env_steps"] for h in hist]
    assert np.diff([0.0] + steps).tolist() == [2 * 2 * h for h in (4, 4, 8, 8, 20)]
    best = [h["best_return"] for h in hist]
    assert 39 < best[0] <= 40 and 78 < best[2] <= 80  # upright, 4 and 8 steps (measured 39.99 and 79.9)
    assert best[4] <= 20 * (10 - (np.pi - 0.011) ** 2)  # hanging (within 0.011 rad of straight down), 20 steps
    # interrupted after iteration 3 (inside the second stage), resumed: the uninterrupted run
    path = tmp_path / "b.eqx"
    state = full.trainer.init(key)
    for _ in range(3):
        state, _ = full.trainer.update(state)
    head = optim.checkpoint.read_header(tmp_path / "a.eqx")
    optim.checkpoint.save(path, state, **{**head, "iteration": 3, "history": hist[:3]})
    resumed = optim.train(cfg, task, policy, key, checkpoint=path, resume=True, seed=2, progress=False)
    assert states_equal(resumed.state, full.state) and [h["best_return"] for h in resumed.history] == best
    scanned, metrics = jax.jit(optim.scan_train(full.trainer))(key)
    assert states_equal(scanned, full.state)
    assert metrics["training_horizon"].tolist() == [4, 4, 8, 8, 20]
