"""Optimisers: config validation, CEM on a quadratic, APG and CE-APG reaching stated returns on small
pendulum tasks, non-finite candidates, checkpoints (round trip, corrupt, mismatched), resume equals an
uninterrupted run, and 4 forced host devices give the single-device result."""

import dataclasses
import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange import tasks as lg_tasks
from lagrange.tasks import chain_swingup
from optim import apg, ce_apg, cem, checkpoint, papg
from optim._loop import params_equal, run
from optim.apg import evaluate

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# --------------------------------------------------------------------------- configs
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
        (lambda: apg.APGConfig(learning_rate=-1.0), "learning_rate"),
        (lambda: apg.APGConfig(episodes=0), "episodes"),
        (lambda: papg.PAPGConfig(num_runs=0), "num_runs"),
        (lambda: ce_apg.CEAPGConfig(bodies="mujoco"), r"bodies must be one of \['rods', 'brax_v1'\]"),
        (lambda: apg.APGConfig(bodies="capsules"), "APGConfig.bodies"),
        (lambda: apg.build_task(ce_apg.CEAPGConfig(task="custom", bodies="brax_v1"), lg_tasks.acrobot()), "bodies"),
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


# --------------------------------------------------------------------------- learning
def test_cem_solves_a_quadratic():
    c = jnp.array([1.5, -2.0, 0.3, 4.0, -0.7])
    mu, best = cem.cem(lambda x: -jnp.sum((x - c) ** 2), jnp.zeros(5), jnp.full(5, 2.0), jax.random.PRNGKey(0),
                       iterations=60, num_candidates=64, num_elites=8)
    # the elite spread shrinks geometrically; after 60 iterations the mean sits on the optimum
    np.testing.assert_allclose(mu, c, atol=1e-4)
    assert float(best[-1]) > -1e-6


def _balance_task():
    # a 1 kg, 1 m pendulum that starts within 0.3 rad (and 0.3 rad/s) of upright; torque 5 a N m.
    # Untrained GRU: about 420; zero torque: about 500; a hand-tuned PD controller: 599.8 of 600.
    return chain_swingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=60, noise=0.3, upright=True)


def test_apg_improves_pendulum_balance():
    task = _balance_task()
    cfg = apg.APGConfig(task="custom", iterations=4, steps_per_iteration=50, episodes=8, learning_rate=1e-2,
                        width=8, horizon=60, truncation=10)
    trainer = apg.make_trainer(cfg, task)
    state = trainer.init(jax.random.PRNGKey(0))
    before, _ = evaluate(task, *trainer.policy(state), jax.random.PRNGKey(7), 32)
    for _ in range(cfg.iterations):
        state, metrics = trainer.update(state)
    after, bal = evaluate(task, *trainer.policy(state), jax.random.PRNGKey(7), 32)
    assert float(before.mean()) < 500
    assert float(after.mean()) > 595  # measured 599.9
    assert bool(bal.all())
    assert int(metrics["nonfinite"]) == 0


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


# --------------------------------------------------------------------------- checkpoints and resume
TINY = ce_apg.CEAPGConfig(task="acrobot", num_candidates=4, num_elites=2, iterations=3, apg_steps=2, episodes=1,
                          horizon=20, width=4, fitness_window=1, lr_start=1e-2, lr_end=1e-3)


@pytest.fixture(scope="module")
def tiny_trainer():
    return ce_apg.make_trainer(TINY)


def test_checkpoint_round_trip_and_errors(tiny_trainer, tmp_path):
    cfg = apg.config_to_dict(TINY)
    state, _ = tiny_trainer.update(tiny_trainer.init(jax.random.PRNGKey(1)))
    path = tmp_path / "ckpt.eqx"
    checkpoint.save(path, state, config=cfg, seed=1, history=[{"best_return": 1.0}])
    loaded, head = checkpoint.load(path, tiny_trainer.init(jax.random.PRNGKey(0)), config=cfg)
    assert params_equal(loaded, state)
    assert head["seed"] == 1 and head["version"] == checkpoint.VERSION and head["config"] == cfg
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".ckpt-")]  # no temp file left behind
    old = os.umask(0o022)
    try:  # an ordinary file's mode under the umask (mkstemp alone would leave 0600)
        checkpoint.save(tmp_path / "mode.eqx", state, config=cfg)
    finally:
        os.umask(old)
    assert (tmp_path / "mode.eqx").stat().st_mode & 0o777 == 0o644

    other = dict(cfg, num_elites=3)
    with pytest.raises(checkpoint.CheckpointError, match="num_elites"):
        checkpoint.load(path, state, config=other)
    data = path.read_bytes()
    (tmp_path / "cut.eqx").write_bytes(data[: len(data) - 40])
    with pytest.raises(checkpoint.CheckpointError, match="corrupt"):
        checkpoint.load(tmp_path / "cut.eqx", state)
    (tmp_path / "junk.eqx").write_bytes(b"\x00\xffnot a checkpoint")
    with pytest.raises(checkpoint.CheckpointError, match="not a lagrange checkpoint"):
        checkpoint.load(tmp_path / "junk.eqx", state)
    head_v2 = json.dumps({"format": checkpoint.FORMAT, "version": 99, "config": cfg}).encode()
    (tmp_path / "v2.eqx").write_bytes(head_v2 + b"\n" + data.split(b"\n", 1)[1])
    with pytest.raises(checkpoint.CheckpointError, match="version 99"):
        checkpoint.load(tmp_path / "v2.eqx", state)


def test_resume_equals_uninterrupted(tiny_trainer, tmp_path):
    key = jax.random.PRNGKey(3)
    full, hist_full = run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "a.eqx"), progress=False, seed=3)
    # "killed" after 1 iteration, then resumed from its checkpoint
    run(tiny_trainer, key, iterations=1, ckpt_path=str(tmp_path / "b.eqx"), progress=False, seed=3)
    resumed, hist = run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "b.eqx"), resume=True,
                        progress=False, seed=3)
    assert int(resumed.iteration) == 3 and len(hist) == 3
    assert params_equal(resumed, full)
    assert [h["best_return"] for h in hist] == [h["best_return"] for h in hist_full]
    assert not params_equal(resumed.mean, tiny_trainer.init(key).mean)  # it did train
    with pytest.raises(checkpoint.CheckpointError, match="seed"):
        run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "b.eqx"), resume=True, progress=False, seed=4)
    # a shorter run (e.g. --quick) cannot resume a longer one: it would report the longer run as its own
    with pytest.raises(checkpoint.CheckpointError, match="iterations=2"):
        run(tiny_trainer, key, iterations=2, ckpt_path=str(tmp_path / "b.eqx"), resume=True, progress=False, seed=3)


def test_resume_a_checkpoint_written_before_a_config_field_existed(tiny_trainer, tmp_path):
    """A config field added later (``upright_starts``) matches an older checkpoint at its default, and only then."""
    key = jax.random.PRNGKey(3)
    path = str(tmp_path / "old.eqx")
    state, hist = run(tiny_trainer, key, iterations=1, ckpt_path=path, progress=False, seed=3)
    head = checkpoint.read_header(path)
    old = {k: v for k, v in head["config"].items() if k != "upright_starts"}
    checkpoint.save(path, state, config=old, seed=3, iteration=1, history=hist)
    resumed, hist2 = run(tiny_trainer, key, iterations=2, ckpt_path=path, resume=True, progress=False, seed=3)
    assert int(resumed.iteration) == 2 and len(hist2) == 2
    checkpoint.save(path, state, config=old, seed=3, iteration=1, history=hist)
    other = ce_apg.make_trainer(dataclasses.replace(TINY, upright_starts=0.5))
    with pytest.raises(checkpoint.CheckpointError, match="upright_starts"):
        run(other, key, iterations=2, ckpt_path=path, resume=True, progress=False, seed=3)


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


_SHARDED = textwrap.dedent(
    """
    import json, jax
    jax.config.update("jax_enable_x64", True)
    from optim import ce_apg
    cfg = ce_apg.CEAPGConfig(task="acrobot", num_candidates=6, num_elites=2, iterations=2, apg_steps=2,
                             episodes=1, horizon=20, width=4, fitness_window=1, lr_start=1e-2, lr_end=1e-3)
    tr = ce_apg.make_trainer(cfg)
    s = tr.init(jax.random.PRNGKey(11))
    for _ in range(2):
        s, m = tr.update(s)
    print(json.dumps({"devices": len(jax.devices()), "mean": s.mean.tolist(), "std": s.std.tolist(),
                      "best": s.best.tolist(), "fitness": float(m["best_return"])}))
    """
)


def test_sharded_equals_single_device():
    """6 candidates on 4 forced host devices (padded to 8) give the single-device result."""
    outs = []
    for flags in ("--xla_force_host_platform_device_count=4", ""):
        env = dict(os.environ, XLA_FLAGS=flags, JAX_PLATFORMS="cpu")
        proc = subprocess.run([sys.executable, "-c", _SHARDED], capture_output=True, text=True, env=env, cwd=ROOT,
                              timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        outs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    four, one = outs
    assert (four["devices"], one["devices"]) == (4, 1)
    # same computation per candidate; only XLA's fusion may differ: float64 round-off
    for k in ("mean", "std", "best"):
        np.testing.assert_allclose(four[k], one[k], rtol=1e-9, atol=1e-12)
    assert four["fitness"] == pytest.approx(one["fitness"], rel=1e-9)


def test_papg_keeps_the_best_run():
    cfg = papg.PAPGConfig(task="acrobot", num_runs=3, iterations=1, apg_steps=2, episodes=1, horizon=20, width=4,
                          fitness_window=1)
    trainer = papg.make_trainer(cfg)
    state, metrics = trainer.update(trainer.init(jax.random.PRNGKey(0)))
    i = int(jnp.argmax(state.fitness))
    assert float(metrics["best_return"]) == float(state.fitness[i])
    policy, _ = trainer.policy(state)
    flat, _ = apg.flatten_policy(policy)
    np.testing.assert_array_equal(flat, state.params[i])
    assert len(set(np.asarray(state.fitness).tolist())) == 3  # independent runs


_CORES = textwrap.dedent(
    """
    import json, warnings
    import jax, jax.numpy as jnp
    import optim
    from optim.devices import use_cpu_cores
    got = use_cpu_cores(3)
    n = len(jax.devices("cpu"))
    jnp.ones(2).sum().block_until_ready()  # JAX has started: the count is fixed now
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        again = use_cpu_cores(5)
    print(json.dumps({"got": got, "devices": n, "again": again, "warned": [str(x.message) for x in w]}))
    """
)


def test_use_cpu_cores_splits_the_host_before_jax_starts():
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env["JAX_PLATFORMS"] = "cpu"
    proc = subprocess.run([sys.executable, "-c", _CORES], capture_output=True, text=True, env=env, cwd=ROOT,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert (out["got"], out["devices"], out["again"]) == (3, 3, 3)
    assert len(out["warned"]) == 1 and "use_cpu_cores(5)" in out["warned"][0]


@pytest.mark.parametrize("n", [0, -1, 1.5, True])
def test_use_cpu_cores_rejects_bad_counts(n):
    from optim.devices import use_cpu_cores

    with pytest.raises(ValueError, match="n must be an integer >= 1"):
        use_cpu_cores(n)
