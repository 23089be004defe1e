"""CE-APG (optim/ce_apg.py): config checks naming the field, the paper's and laptop presets, the warm-up schedule,
a stated return on a small problem (a pendulum swung up and balanced, 850 of 1000), non-finite candidates, the
training starts (upright, noise) kept apart from the evaluated task, a checkpoint that rebuilds its trainer, and
``make_train`` as one jittable function equal to the host loop."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange import tasks as lg_tasks
from lagrange.tasks import chain_swingup
from optim import apg, ce_apg, cem, checkpoint
from optim._loop import params_equal, run
from optim.apg import evaluate
from tests.helpers import tiny_ce_apg_config


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: ce_apg.CEAPGConfig(num_candidates=0), "num_candidates"),
        (lambda: ce_apg.CEAPGConfig(num_candidates=4, num_elites=5), "num_elites"),
        (lambda: ce_apg.CEAPGConfig(lr_start=-1e-3), "lr_start"),
        (lambda: ce_apg.CEAPGConfig(lr_end=float("nan")), "lr_end"),
        (lambda: ce_apg.CEAPGConfig(task="hopper"), "task"),
        (lambda: ce_apg.CEAPGConfig(init_std=-0.1), "init_std"),
        (lambda: ce_apg.CEAPGConfig(apg_steps=3, fitness_window=5), "fitness_window"),
        (lambda: ce_apg.CEAPGConfig(policy="transformer"), "policy"),
        (lambda: ce_apg.CEAPGConfig(upright_starts=1.5), "upright_starts"),
        (lambda: ce_apg.CEAPGConfig(upright_starts=-0.1), "upright_starts"),
        (lambda: ce_apg.CEAPGConfig(train_noise=-0.1), "CEAPGConfig.train_noise must be a finite number >= 0"),
        (lambda: ce_apg.CEAPGConfig(train_noise=float("inf")), "train_noise"),
        (lambda: ce_apg.CEAPGConfig(warmup_horizons=(100, 0)), r"warmup_horizons\[1\]"),
        (lambda: ce_apg.CEAPGConfig(warmup_horizons="100"), "warmup_horizons"),
        (lambda: ce_apg.CEAPGConfig(warmup_horizons=(100,), warmup_iterations=0), "warmup_iterations"),
        (lambda: ce_apg.CEAPGConfig(warmup_upright=1.5), "warmup_upright"),
        (lambda: ce_apg.CEAPGConfig(iterations=20, warmup_horizons=(100, 200), warmup_iterations=15), "iterations"),
        (lambda: ce_apg.CEAPGConfig(apg_steps=0, warmup_horizons=(100,)), "warmup_horizons"),
        (lambda: ce_apg.CEAPGConfig(bodies="mujoco"), r"bodies must be one of \['rods', 'brax_v1'\]"),
    ],
)
def test_bad_configs_name_the_field(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_bodies_field_builds_the_brax_v1_task():
    """``bodies`` reaches the trainer's task: the default is the rods task unchanged, "brax_v1" the authors' bodies."""
    rods = apg.build_task(ce_apg.CEAPGConfig.laptop("acrobot"))
    brax = apg.build_task(ce_apg.CEAPGConfig.laptop("acrobot", bodies="brax_v1"))
    assert rods.trig and brax.trig
    for task, bodies in ((rods, "rods"), (brax, "brax_v1")):
        want = lg_tasks.make_task("acrobot", bodies).chain
        for field in ("mass", "length", "com", "inertia"):
            np.testing.assert_array_equal(getattr(task.chain, field), getattr(want, field))
    assert not np.allclose(brax.chain.inertia, rods.chain.inertia)
    # a task passed to make_trainer may carry the config's bodies (a Brax v1 task with its own starts); a task on
    # other bodies is refused, naming the field
    cfg = ce_apg.CEAPGConfig.laptop("acrobot", bodies="brax_v1")
    given = dataclasses.replace(lg_tasks.make_task("acrobot", "brax_v1"), upright=1.0)
    assert apg.build_task(cfg, given).upright == 1.0
    with pytest.raises(ValueError, match=r"CEAPGConfig.bodies='brax_v1'.*got a task with bodies='rods'"):
        apg.build_task(cfg, lg_tasks.make_task("acrobot"))


def test_paper_presets():
    c = ce_apg.CEAPGConfig.paper("acrobot")
    assert (c.num_candidates, c.num_elites, c.iterations, c.apg_steps, c.episodes, c.horizon) == (24, 8, 200, 100, 4, 500)
    assert (c.init_std, c.lr_start, c.lr_end, c.fitness_window, c.width) == (0.05, 1e-3, 1e-6, 5, 16)
    assert c.env_steps_per_iteration() == 4_800_000
    assert ce_apg.CEAPGConfig.paper("double_cartpole").width == 32
    # the paper's schedule: 10^((-3 (T - i) - 6 i) / T)
    for i in (0, 50, 200):
        assert float(c.learning_rate(i)) == pytest.approx(10 ** ((-3 * (200 - i) - 6 * i) / 200), rel=1e-5)
    assert float(c.learning_rate(260)) == pytest.approx(1e-6, rel=1e-5)  # past the planned iterations: lr_end
    m = cem.config("cartpole")
    assert (m.apg_steps, m.iterations) == (0, 2000)
    with pytest.raises(ValueError, match="apg_steps"):
        cem.make_trainer(c)


def test_laptop_presets():
    a = ce_apg.CEAPGConfig.laptop("acrobot")
    assert (a.num_candidates, a.num_elites, a.iterations, a.apg_steps, a.episodes) == (24, 6, 150, 50, 2)
    assert a.trig_observation and a.env_steps_per_iteration() == 1_200_000
    assert a.warmup_horizons == () and a.total_env_steps() == 150 * 1_200_000
    assert ce_apg.CEAPGConfig.laptop("double_cartpole").width == 32
    assert ce_apg.CEAPGConfig.laptop("cartpole", iterations=3).iterations == 3
    with pytest.raises(ValueError, match="task"):
        ce_apg.CEAPGConfig.laptop("hopper")


def test_with_iterations_compresses_the_warmup():
    """A shorter run of the same protocol (``--iterations``, ``--quick``): the warm-up keeps its share of the
    iterations, and is dropped once a stage would get less than one."""
    # 20 iterations of 300-step and 20 of 400-step hanging episodes, then 110 of the task's 500 (README)
    a = ce_apg.CEAPGConfig.laptop("acrobot", warmup_horizons=(300, 400), warmup_iterations=20, warmup_upright=0.0)
    assert a.total_env_steps() == 24 * 50 * 2 * (20 * 300 + 20 * 400 + 110 * 500)
    assert a.with_iterations(150) == a
    q = a.with_iterations(45)
    assert (q.iterations, q.warmup_horizons, q.warmup_iterations) == (45, (300, 400), 6)
    assert [q.training_horizon(i) for i in (0, 5, 6, 11, 12, 44)] == [300, 300, 400, 400, 500, 500]
    assert a.with_iterations(10).warmup_iterations == 1
    one = a.with_iterations(1)
    assert (one.iterations, one.warmup_horizons, one.training_horizon(0)) == (1, (), 500)
    c = ce_apg.CEAPGConfig.laptop("cartpole")  # no warm-up: only the iteration count changes
    assert c.with_iterations(3) == dataclasses.replace(c, iterations=3)


def test_custom_task_must_be_passed():
    with pytest.raises(ValueError, match="custom"):
        ce_apg.make_trainer(ce_apg.CEAPGConfig(task="custom"))


def test_trig_observation_applies_to_a_passed_task():
    chain = lg.Chain([lg.Link("revolute", mass=1.0, length=1.0, gear=5.0)])
    task = chain_swingup(chain, dt=0.05, horizon=20)
    on = ce_apg.make_trainer(ce_apg.CEAPGConfig(task="custom", horizon=20, trig_observation=True), task).task
    off = ce_apg.make_trainer(ce_apg.CEAPGConfig(task="custom", horizon=20), task).task
    assert on.trig and on.observation_size == 3 and not off.trig and off.observation_size == 2


def test_ce_apg_swings_a_pendulum_up():
    """CE-APG swings a torque-limited pendulum (5 N m against 4.9 N m of gravity at horizontal) up
    from hanging and balances it in 10 small iterations (8 x 20 x 2 x 100 env steps each)."""
    task = chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=100)
    cfg = ce_apg.CEAPGConfig(task="custom", num_candidates=8, num_elites=3, iterations=10, apg_steps=20, episodes=2,
                             horizon=100, width=8, lr_start=1e-2, lr_end=1e-3, init_std=0.3, truncation=10)
    trainer = ce_apg.make_trainer(cfg, task)
    state = trainer.init(jax.random.PRNGKey(0))
    for _ in range(cfg.iterations):
        state, metrics = trainer.update(state)
    ret, bal = evaluate(task, *trainer.policy(state), jax.random.PRNGKey(7), 32)
    assert float(ret.mean()) > 850  # of 1000; measured 918; a hanging pendulum scores 10 - pi^2 per step (~13)
    assert bool(bal.all())


def test_nonfinite_candidates_get_minus_infinity_and_do_not_poison():
    # a gear of 1e300 drives velocities to ~1e298 in one step: their squares overflow to inf, then NaN
    task = chain_swingup(lg.systems.pendulum(gear=1e300), dt=0.05, horizon=5)
    cfg = ce_apg.CEAPGConfig(task="custom", num_candidates=4, num_elites=2, iterations=1, apg_steps=2, episodes=1,
                             horizon=5, width=4, fitness_window=1, init_std=0.1)
    trainer = ce_apg.make_trainer(cfg, task)
    state, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
    assert int(metrics["nonfinite"]) == 4
    assert float(metrics["best_return"]) == -np.inf
    assert bool(jnp.all(jnp.isfinite(state.mean))) and bool(jnp.all(jnp.isfinite(state.std)))


def test_upright_starts_train_on_balanced_starts_and_evaluate_hanging():
    """``upright_starts`` changes the episodes candidates are scored on, never the task the trainer evaluates.
    With a zero policy (mean 0, std 0) a 1 kg pendulum left hanging earns about 10 - pi^2 per step; started
    upright it earns nearly 10 per step while it slowly starts to topple."""
    task = chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=20)
    fitness = {}
    for p in (0.0, 1.0):
        cfg = ce_apg.CEAPGConfig(task="custom", num_candidates=2, num_elites=1, iterations=1, apg_steps=0,
                                 episodes=2, horizon=20, width=4, init_std=0.0, upright_starts=p)
        trainer = ce_apg.make_trainer(cfg, task)
        assert trainer.task.upright == 0  # evaluation keeps the hanging start
        _, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
        fitness[p] = float(metrics["best_return"])
    # hanging within ~0.011 rad of straight down (reset noise 0.01 on angle and speed): at most 20 (10 - (pi - 0.011)^2)
    assert fitness[0.0] <= 20 * (10 - (np.pi - 0.011) ** 2)
    assert fitness[1.0] > 190  # of 200 for a perfect hold; measured 199.9 (a 0.01 rad tilt grows e^3.8t, ~0.4 rad at 1 s)


def test_train_noise_widens_the_training_starts_and_evaluates_the_task():
    """``train_noise`` changes the starts candidates are scored on, never the task the trainer evaluates. With a
    zero policy (no torque) a pendulum started exactly hanging and at rest stays there: 10 - pi^2 per step; the
    task's own +-0.01 is the default (``None``), bit for bit."""
    task = chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=20)
    fitness = {}
    for noise in (None, 0.01, 0.0, 0.5):
        cfg = ce_apg.CEAPGConfig(task="custom", num_candidates=2, num_elites=1, iterations=1, apg_steps=0,
                                 episodes=2, horizon=20, width=4, init_std=0.0, train_noise=noise)
        trainer = ce_apg.make_trainer(cfg, task)
        assert trainer.task.noise == 0.01  # evaluation keeps the task's noise
        _, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
        fitness[noise] = float(metrics["best_return"])
    assert fitness[0.01] == fitness[None]
    np.testing.assert_allclose(fitness[0.0], 20 * (10 - np.pi ** 2), rtol=1e-5)
    assert fitness[None] != fitness[0.0]
    # starts up to 0.5 rad and 0.5 rad/s off hanging swing nearer upright: measured 36.2 against 3.3
    assert fitness[0.5] > fitness[None] + 5


def test_warmup_horizons_schedule_the_training_episodes(tmp_path):
    """The warm-up trains and scores candidates on ``warmup_horizons[i]``-step episodes from upright for
    ``warmup_iterations`` iterations each, then on the full hanging task; env steps follow the stage; a run
    resumed across a stage boundary (its config holds a tuple, stored as JSON) equals an uninterrupted one and
    the one jittable ``make_train``. With a zero policy (std 0, a negligible learning rate) a 1 kg pendulum
    started upright earns nearly 10 per step; left hanging about 10 - pi^2."""
    task = chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=20)
    cfg = ce_apg.CEAPGConfig(task="custom", num_candidates=2, num_elites=1, iterations=5, apg_steps=1, episodes=2,
                             horizon=20, width=4, fitness_window=1, init_std=0.0, lr_start=1e-12, lr_end=1e-12,
                             warmup_horizons=[4, 8], warmup_iterations=2)
    assert cfg.warmup_horizons == (4, 8) and [cfg.training_horizon(i) for i in range(5)] == [4, 4, 8, 8, 20]
    assert cfg.total_env_steps() == 2 * 1 * 2 * (4 + 4 + 8 + 8 + 20)
    trainer = ce_apg.make_trainer(cfg, task)
    assert trainer.task.horizon == 20 and trainer.task.upright == 0  # evaluation: the full hanging task
    key = jax.random.PRNGKey(2)
    state, hist = run(trainer, key, iterations=5, ckpt_path=str(tmp_path / "a.eqx"), progress=False, seed=2)
    assert [h["training_horizon"] for h in hist] == [4, 4, 8, 8, 20]
    steps = [h["env_steps"] for h in hist]
    assert np.diff([0.0] + steps).tolist() == [2 * 2 * h for h in (4, 4, 8, 8, 20)]
    best = [h["best_return"] for h in hist]
    assert 39 < best[0] <= 40 and 78 < best[2] <= 80  # upright, 4 and 8 steps (measured 39.99 and 79.9)
    assert best[4] <= 20 * (10 - (np.pi - 0.011) ** 2)  # hanging (within 0.011 rad of straight down), 20 steps
    run(trainer, key, iterations=3, ckpt_path=str(tmp_path / "b.eqx"), progress=False, seed=2)
    resumed, hist_b = run(trainer, key, iterations=5, ckpt_path=str(tmp_path / "b.eqx"), resume=True,
                          progress=False, seed=2)
    assert params_equal(resumed, state) and [h["best_return"] for h in hist_b] == best
    scanned, metrics = jax.jit(ce_apg.make_train(cfg, task))(key)
    assert params_equal(scanned, state)
    assert metrics["training_horizon"].tolist() == [4, 4, 8, 8, 20]


TINY = tiny_ce_apg_config()


@pytest.fixture(scope="module")
def tiny_trainer():
    return ce_apg.make_trainer(TINY)


def test_load_checkpoint_rebuilds_the_trainer_from_the_header(tiny_trainer, tmp_path):
    """``ce_apg.load_checkpoint(path)`` needs no config: the header's gives back the same trainer and state."""
    key = jax.random.PRNGKey(3)
    path = str(tmp_path / "run.eqx")
    state, _ = run(tiny_trainer, key, iterations=2, ckpt_path=path, progress=False, seed=3)
    trainer, loaded = ce_apg.load_checkpoint(path)
    assert trainer.config == TINY and params_equal(loaded, state) and int(loaded.iteration) == 2
    plain = apg.make_trainer(apg.APGConfig(task="acrobot", iterations=1, episodes=1, horizon=5, width=4))
    checkpoint.save(tmp_path / "apg.eqx", plain.init(key), config=apg.config_to_dict(plain.config))
    with pytest.raises(checkpoint.CheckpointError, match="not a CE-APG checkpoint.*APGConfig"):
        ce_apg.load_checkpoint(tmp_path / "apg.eqx")
    head = checkpoint.read_header(path)
    checkpoint.save(tmp_path / "new.eqx", state, config=dict(head["config"], later_field=1))
    with pytest.raises(checkpoint.CheckpointError, match="later_field"):
        ce_apg.load_checkpoint(tmp_path / "new.eqx")


def test_make_train_is_one_jittable_function(tiny_trainer):
    """``make_train(config)(key)`` (lax.scan over iterations) reaches the host loop's state."""
    state, metrics = jax.jit(ce_apg.make_train(TINY))(jax.random.PRNGKey(5))
    host = tiny_trainer.init(jax.random.PRNGKey(5))
    for _ in range(TINY.iterations):
        host, _ = tiny_trainer.update(host)
    assert metrics["best_return"].shape == (TINY.iterations,)
    for a, b in zip(jax.tree_util.tree_leaves(state), jax.tree_util.tree_leaves(host)):
        np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-9, atol=1e-12)
