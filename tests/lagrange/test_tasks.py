"""The swing-up tasks (lagrange/tasks/swingup.py, base.py, balance.py): resets, angle conventions, observations and
rewards by hand, the integrator against Dopri8, energy conservation, the balanced criterion on synthetic
trajectories, the class structure (abstract bases, final tasks, body-set constructors), and the shapes a step takes."""

import dataclasses
import inspect

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange import systems, tasks
from lagrange.chain import Chain, Link
from lagrange.planar.lower import lower as planar
from lagrange.tasks import Acrobot, Cartpole, ChainSwingup, DiffRLCartpole, DoubleCartpole, TaskState
from lagrange.tasks.base import joint_kinds
from tests.helpers import states_equal

FINAL = (Acrobot, Cartpole, DoubleCartpole, ChainSwingup, DiffRLCartpole)


@pytest.mark.parametrize("name, n, obs", [("acrobot", 2, 4), ("cartpole", 2, 4), ("double_cartpole", 3, 8)])
def test_reset_hangs_with_bounded_noise(name, n, obs):
    task = tasks.PAPER_TASKS[name].rods()

    @jax.jit
    def draw(key):  # the resets, their angles and an observation: one compiled program
        s = jax.vmap(task.reset)(jax.random.split(key, 256))
        return s, jax.vmap(task.angles)(s), task.observe(jax.tree_util.tree_map(lambda x: x[0], s))

    s, th, first = draw(jax.random.PRNGKey(0))
    assert s.q.shape == (256, n) and s.qd.shape == (256, n)
    assert float(jnp.max(jnp.abs(s.q))) <= 0.01 and float(jnp.max(jnp.abs(s.qd))) <= 0.01
    assert float(jnp.max(jnp.abs(s.q))) > 0.009  # the noise is really there and uniform on [-0.01, 0.01]
    # the first pole hangs: |th1| = pi - |noise|, wrapped into (-pi, pi]
    np.testing.assert_allclose(np.abs(th[:, 0]), np.pi - np.abs(s.q[:, task.first_pole]), atol=1e-12)
    assert first.shape == (obs,)
    assert task.horizon == 500


def test_upright_fraction_of_starts():
    """``upright=p`` starts balanced with probability p; p = 0 draws exactly the paper's hanging starts."""
    keys = jax.random.split(jax.random.PRNGKey(1), 4000)
    for task in (Acrobot.rods(), DoubleCartpole.rods()):
        i = task.first_pole

        @jax.jit
        def draw(keys):  # the three kinds of starts and the angles: one compiled program
            mixed = jax.vmap(dataclasses.replace(task, upright=0.25).reset)(keys)
            always = jax.vmap(dataclasses.replace(task, upright=1).reset)(keys)
            return (jax.vmap(task.reset)(keys), mixed, always, jax.vmap(task.angles)(mixed),
                    jax.vmap(task.angles)(always))

        paper, mixed, always, mixed_angles, always_angles = draw(keys)
        up = np.asarray(jnp.abs(mixed_angles[:, 0]) < 0.1)
        assert 0.22 < up.mean() < 0.28  # binomial(4000, 0.25): std 0.007
        # the same noise either way: only the first pole's angle moves, by exactly pi when upright (the velocities
        # to two ulps of the noise's scale, 0.01: the three draws are fused differently in the one program)
        np.testing.assert_allclose(mixed.qd, paper.qd, rtol=0, atol=2 * np.finfo(np.float64).eps * 0.01)
        np.testing.assert_allclose(mixed.q[:, i] - paper.q[:, i], np.pi * up, atol=1e-6)
        np.testing.assert_allclose(always.q[:, i] - paper.q[:, i], np.pi, atol=1e-6)
        assert bool(jnp.all(jnp.abs(always_angles[:, 0]) <= 0.01 + 1e-6))
    with pytest.raises(ValueError, match=r"Acrobot.upright must be a number in \[0, 1\], got 1.5"):
        dataclasses.replace(Acrobot.rods(), upright=1.5)
    with pytest.raises(ValueError, match="upright"):
        Acrobot.rods(upright=-0.1)


def test_start_states():
    """``starts=X`` draws each reset's (q, qd) uniformly from the rows of X, plus the task's usual noise; the
    ``upright`` coin still comes first; a wrong shape or a non-finite row is refused naming the field."""
    task = DoubleCartpole.rods()
    X = jnp.asarray([[0.5, 1.0, -1.0, 2.0, 0.0, 3.0], [-0.5, 2.0, 0.5, 0.0, -4.0, 1.0], [0.0, 3.0, 0.0, 0.0, 0.0, 0.0]])
    keys = jax.random.split(jax.random.PRNGKey(2), 3000)

    @jax.jit
    def draw(keys):  # the paper's starts, the drawn rows, both mixed with upright ones: one compiled program
        mixed = jax.vmap(dataclasses.replace(task, starts=X, upright=0.5).reset)(keys)
        return (jax.vmap(task.reset)(keys), jax.vmap(dataclasses.replace(task, starts=X).reset)(keys), mixed,
                jax.vmap(task.angles)(mixed))

    paper, drawn, mixed, mixed_angles = (jax.tree_util.tree_map(np.asarray, x) for x in draw(keys))
    x = np.concatenate([drawn.q - paper.q, drawn.qd - paper.qd], axis=1)  # the drawn row: the noise is the same
    row = np.argmin(np.abs(x[:, None, :] - np.asarray(X)[None]).max(-1), axis=1)
    np.testing.assert_allclose(x, np.asarray(X)[row], atol=1e-6)
    assert np.all(np.abs(np.bincount(row, minlength=3) / 3000 - 1 / 3) < 0.03)  # uniform: std 0.009
    up = (np.abs(mixed_angles[:, 0]) <= 0.01 + 1e-6) & (np.abs(mixed.qd).max(-1) <= 0.01)
    assert 0.46 < up.mean() < 0.54
    for bad in (X[:, :4], X[0], jnp.zeros((0, 6))):
        with pytest.raises(ValueError, match=r"DoubleCartpole.starts must be an array of shape \(K >= 1, 2 n = 6\)"):
            dataclasses.replace(task, starts=bad)
    with pytest.raises(ValueError, match="DoubleCartpole.starts must be finite"):
        dataclasses.replace(task, starts=X.at[1, 2].set(jnp.nan))


def test_paper_parameters():
    a, c, d = Acrobot.rods(), Cartpole.rods(), DoubleCartpole.rods()
    assert (a.dt, c.dt, d.dt) == (0.01, 0.04, 0.01)
    assert (a.horizon, a.substeps, a.noise, a.upright, a.starts) == (500, 1, 0.01, 0.0, None)
    assert isinstance(a.solver, lg.RK4) and (a.trig, c.trig, d.trig) == (False, False, True)
    np.testing.assert_allclose(a.chain.mass, [2.5, 2.5]) and np.testing.assert_allclose(a.chain.length, [1, 1])
    np.testing.assert_allclose(a.chain.gear, [25.0])
    assert a.chain.actuated == (1,)  # the elbow; the shoulder is passive
    np.testing.assert_allclose(c.chain.mass, [10.47, 5.02]) and np.testing.assert_allclose(c.chain.gear, [100.0])
    np.testing.assert_allclose(d.chain.mass, [10.47, 5.02, 5.02]) and np.testing.assert_allclose(d.chain.gear, [1000.0])
    # the first pole's joint follows the cart's
    assert (a.first_pole, c.first_pole, d.first_pole) == (0, 1, 1) and (a.n_links, c.n_links, d.n_links) == (2, 1, 2)
    assert (a.cart, c.cart, d.cart) == (False, True, True) and (a.action_size, c.action_size, d.action_size) == (1,) * 3
    # a task on a chain of one's own: the class's dt, the paper's other fields, no body-set label
    own = Acrobot(systems.acrobot(masses=(1.0, 3.0)))
    assert (own.dt, own.horizon, own.bodies) == (0.01, 500, None)
    np.testing.assert_allclose(own.chain.mass, [1.0, 3.0])


def test_brax_v1_bodies():
    """``brax_v1()`` changes the chain (the authors' hinge spacings, inertia 1 kg m^2, ``systems.BRAX_V1``) and
    nothing else of the task; ``rods()`` is this library's rods, the catalogue's default chains."""
    for name, cls in tasks.PAPER_TASKS.items():
        rods, brax = cls.rods(), cls.brax_v1()
        want_rods, want_brax = getattr(systems, name)(), getattr(systems, name)(**systems.BRAX_V1[name])
        for field in ("mass", "length", "com", "inertia", "gear", "damping"):
            np.testing.assert_array_equal(getattr(planar(rods.chain), field), getattr(planar(want_rods), field))
            np.testing.assert_array_equal(getattr(planar(brax.chain), field), getattr(planar(want_brax), field))
        assert (joint_kinds(rods.chain) == joint_kinds(brax.chain) == joint_kinds(want_brax)
                == joint_kinds(want_rods))
        assert (brax.name, brax.dt, brax.horizon, brax.noise, brax.substeps) == (rods.name, rods.dt, rods.horizon,
                                                                                  rods.noise, rods.substeps)
        np.testing.assert_allclose(brax.chain.gear, rods.chain.gear)
        poles = slice(brax.first_pole, None)
        np.testing.assert_allclose(planar(brax.chain).inertia[poles], 1.0)
        assert np.all(np.asarray(planar(rods.chain).inertia[poles]) < 0.5)
    a = planar(Acrobot.brax_v1().chain)
    np.testing.assert_allclose(a.mass, [2.5, 2.5]) and np.testing.assert_allclose(a.length, [0.9, 0.9])
    np.testing.assert_allclose(a.com, [0.45, 0.45]) and np.testing.assert_allclose(a.inertia, [1.0, 1.0])
    d = planar(DoubleCartpole.brax_v1().chain)
    np.testing.assert_allclose(d.com[1:], [0.3, 0.3]) and np.testing.assert_allclose(d.length[1:], [0.6, 0.6])
    # the task records its bodies (a float64 rebuild, research.swingup_lqr.rerun_float64, reads them back)
    assert (Acrobot.rods().bodies, Acrobot.brax_v1().bodies) == ("rods", "brax_v1")
    assert Acrobot(systems.acrobot()).bodies is None and ChainSwingup(Acrobot.rods().chain).bodies is None
    with pytest.raises(ValueError, match=r"Acrobot.bodies must be None or one of \['rods', 'brax_v1'\], got 'brax'"):
        dataclasses.replace(Acrobot.rods(), bodies="brax")


def test_wrap_range():
    x = jnp.linspace(-20, 20, 10001)
    w = tasks.wrap(x)
    assert float(w.min()) > -np.pi and float(w.max()) <= np.pi
    np.testing.assert_allclose(np.cos(w), np.cos(x), atol=1e-12)
    assert float(tasks.wrap(jnp.pi)) == pytest.approx(np.pi) and float(tasks.wrap(-jnp.pi)) == pytest.approx(np.pi)


def _state(q, qd):
    return tasks.TaskState(jnp.asarray(q, float), jnp.asarray(qd, float))


def test_observations_and_rewards_by_hand():
    a = Acrobot.rods()
    s = _state([np.pi + 0.3, -0.2], [1.0, -2.0])  # first link 0.3 past upright, elbow bent -0.2
    np.testing.assert_allclose(a.observe(s), [0.3, -0.2, 1.0, -2.0], atol=1e-12)
    assert float(a.reward(None, None, s)) == pytest.approx(10 - 0.09 - 0.04 - 0.01 * 5)
    assert float(a.reward(None, None, _state([np.pi, 0], [0, 0]))) == 10.0
    assert float(a.reward(None, None, _state([0, 0], [0, 0]))) == pytest.approx(10 - np.pi**2)

    c = Cartpole.rods()
    s = _state([0.5, np.pi - 0.4], [0.1, 0.7])
    np.testing.assert_allclose(c.observe(s), [0.5, -0.4, 0.1, 0.7], atol=1e-12)
    assert float(c.reward(None, None, s)) == pytest.approx(-0.16)
    ct = Cartpole.rods(trig=True)
    np.testing.assert_allclose(ct.observe(s), [0.5, np.sin(-0.4), np.cos(-0.4), 0.1, 0.7], atol=1e-12)
    assert (c.observation_size, ct.observation_size) == (4, 5)

    d = DoubleCartpole.rods()
    s = _state([0.5, np.pi + 0.1, 0.2], [0.3, 1.0, 2.0])
    th = np.array([0.1, 0.2])
    np.testing.assert_allclose(d.observe(s), [0.5, *np.sin(th), *np.cos(th), 0.3, 1.0, 2.0], atol=1e-12)
    assert float(d.reward(None, None, s)) == pytest.approx(10 - (0.01 + 0.04 + 0.25) - 0.01 * 5)

    # a three-link arm: the acrobot's observation and reward over every link
    arm = ChainSwingup(systems.n_link_pendulum(3, gear=2.0))
    s = _state([np.pi - 0.1, 0.3, -0.5], [0.5, -1.0, 2.0])
    np.testing.assert_allclose(arm.observe(s), [-0.1, 0.3, -0.5, 0.5, -1.0, 2.0], atol=1e-12)
    assert float(arm.reward(None, None, s)) == pytest.approx(10 - (0.01 + 0.09 + 0.25) - 0.01 * (0.25 + 1 + 4))
    th = np.array([-0.1, 0.3, -0.5])
    np.testing.assert_allclose(dataclasses.replace(arm, trig=True).observe(s), [*np.sin(th), *np.cos(th), 0.5, -1.0,
                                                                                  2.0], atol=1e-12)
    assert (arm.observation_size, dataclasses.replace(arm, trig=True).observation_size, arm.action_size) == (6, 9, 3)


def test_step_matches_dopri8_and_clips_actions():
    """One RK4 step per interval (the documented choice) stays within 1e-3 rad of Dopri8 at
    rtol = atol = 1e-12 over a whole 500-step acrobot episode under an energetic pumping action
    (measured 1.1e-4; the reset noise it must stay below is 1e-2)."""
    task = Acrobot.rods()
    s0 = _state([0.005, -0.003], [0.0, 0.0])
    t = jnp.arange(500) * task.dt
    a = 0.6 * jnp.sin(2 * jnp.pi * 1.2 * t)[:, None]

    @jax.jit
    def run(s0, a):  # the task's steps, Dopri8's rollout, two clipped steps: one compiled program
        s_end, qs = jax.lax.scan(lambda s, u: (task.step(s, u),) * 2, s0, a)
        ref = lg.simulate(task.chain, s0.q, s0.qd, a, task.dt, lg.Dopri8(), rtol=1e-12, atol=1e-12, max_steps=100000)
        return qs, ref, task.step(s0, jnp.array([3.0])).q, task.step(s0, jnp.array([1.0])).q

    qs, ref, beyond, one = run(s0, a)
    assert float(jnp.max(jnp.abs(qs.q - ref.q[1:]))) < 1e-3
    assert float(jnp.max(jnp.abs(ref.q))) > 1.5  # the trajectory really swings
    # actions beyond [-1, 1] are clipped before the gear
    np.testing.assert_array_equal(beyond, one)


def test_energy_drift_is_at_least_fourth_order():
    """Unactuated, the acrobot conserves energy; RK4's drift over 500 steps of a 2-rad swing is
    small (measured 1.5e-4 J; the swing's potential-energy range is about 50 J) and shrinks at
    least as fast as a fourth-order method's, 2^4 = 16 per halving (accept > 12; measured about
    30, 29, 27 for substeps 1->2->4->8)."""
    task = Acrobot.rods()
    s = _state([2.0, -1.0], [0.0, 0.0])
    e0 = sum(lg.energy(task.chain, s.q, s.qd))

    def drift(t):
        s_end, _ = jax.lax.scan(lambda s, _: (t.step(s, jnp.zeros(1)), None), s, None, length=500)
        return abs(float(sum(lg.energy(t.chain, s_end.q, s_end.qd)) - e0))

    d1, d2 = drift(task), drift(dataclasses.replace(task, substeps=2))
    assert d1 < 1e-3
    assert d1 / d2 > 12


def test_balanced_on_synthetic_trajectories():
    a = Acrobot.rods()
    T = 501
    q = np.zeros((T, 2))
    q[:, 0] = np.pi  # upright, straight
    assert bool(tasks.balanced(a, q))
    early = q.copy()
    early[:350, 0] = 0.0  # hanging until 70 % of the episode: balanced counts only the final 20 %
    assert bool(tasks.balanced(a, early))
    late = q.copy()
    late[-10, 1] = 0.25  # the second link 0.25 rad off for one step in the final 20 %
    assert not bool(tasks.balanced(a, late))
    compensated = q.copy()
    compensated[:, 0] = np.pi + 0.15
    compensated[:, 1] = -0.1  # link 1 at 0.15, link 2 at 0.05 absolute: both within 0.2
    assert bool(tasks.balanced(a, compensated))
    c = Cartpole.rods()
    qc = np.zeros((T, 2))
    qc[:, 0] = 3.0  # the cart position does not matter
    qc[:, 1] = -np.pi + 0.1
    assert bool(tasks.balanced(c, qc))
    batch = np.stack([q, late])
    np.testing.assert_array_equal(tasks.balanced(a, batch), [True, False])


def test_leaves_upright_finds_the_first_step_past_the_tolerance():
    """On built trajectories: the elbow bent 0.3 rad from step 12 (the second link 0.3 rad off), the first link
    0.2 rad off from step 5; the tolerance is on each link's absolute orientation, as ``balanced`` measures it."""
    task = Acrobot.rods()
    q = np.tile([np.pi, 0.0], (2, 30, 1))
    q[0, 12:, 1] = 0.3
    q[1, 5:, 0] = np.pi - 0.2
    got = tasks.leaves_upright(task, q, tolerance=0.25)
    assert isinstance(got, np.ndarray) and np.issubdtype(got.dtype, np.integer)
    np.testing.assert_array_equal(got, [12, -1])  # -1: never leaves
    np.testing.assert_array_equal(tasks.leaves_upright(task, q, tolerance=0.25, from_step=20), [20, -1])
    np.testing.assert_array_equal(tasks.leaves_upright(task, q, tolerance=0.1), [12, 5])
    # the elbow bent back against a leaning shoulder keeps the second link upright: 0.2 rad off the first only
    bent = np.tile([np.pi + 0.2, -0.2], (30, 1))
    assert tasks.leaves_upright(task, bent, tolerance=0.25).shape == () and tasks.leaves_upright(
        task, bent, tolerance=0.25) == -1
    # the cartpole's cart is not a link; a non-finite step counts as having left
    cart = np.tile([5.0, np.pi], (3, 4, 10, 1))
    cart[1, 2, 7:, 1] = np.nan
    want = np.full((3, 4), -1)
    want[1, 2] = 7
    np.testing.assert_array_equal(tasks.leaves_upright(Cartpole.rods(), cart, tolerance=0.1), want)
    for kwargs, field in [({"tolerance": 0.0}, "tolerance"), ({"tolerance": -1.0}, "tolerance"),
                          ({"from_step": -1}, "from_step"), ({"from_step": 30}, "from_step"),
                          ({"from_step": 1.5}, "from_step")]:
        with pytest.raises(ValueError, match=field):
            tasks.leaves_upright(task, q, **{"tolerance": 0.25, **kwargs})
    with pytest.raises(ValueError, match="q must"):
        tasks.leaves_upright(task, q[..., :1], tolerance=0.25)


def test_paper_tasks_and_body_sets():
    """``PAPER_TASKS`` names the paper's three classes by their display names; each has one constructor per body
    set, which labels the task with it; the constructors take the task's fields and apply them as given."""
    assert tasks.PAPER_TASKS == {"acrobot": Acrobot, "cartpole": Cartpole, "double_cartpole": DoubleCartpole}
    assert tasks.BODY_SETS == ("rods", "brax_v1")
    for name, cls in tasks.PAPER_TASKS.items():
        assert cls.name == name
        for bodies in tasks.BODY_SETS:
            task = getattr(cls, bodies)(horizon=7, noise=0.3, upright=0.5, substeps=2)
            assert type(task) is cls and task.bodies == bodies
            assert (task.horizon, task.noise, task.upright, task.substeps) == (7, 0.3, 0.5, 2)
            replaced = dataclasses.replace(getattr(cls, bodies)(), horizon=7, noise=0.3, upright=0.5, substeps=2)
            assert bool(eqx.tree_equal(replaced, task))
    assert Acrobot.rods(trig=True).trig and Acrobot.rods(trig=True).observation_size == 6
    with pytest.raises(TypeError, match="trig"):  # the double cartpole's layout is always trigonometric
        DoubleCartpole.rods(trig=False)


def test_classes_are_abstract_or_final():
    """The tasks are final concrete classes of the abstract ``AbstractTask`` (the swing-ups through
    ``AbstractSwingup``); an abstract class cannot be built; the display name is a class constant, and no string
    field selects a task's behaviour."""
    chain = systems.acrobot()
    with pytest.raises(TypeError, match="abstract"):
        tasks.AbstractTask()
    with pytest.raises(TypeError, match="abstract"):
        tasks.AbstractSwingup(chain)
    for cls in (tasks.AbstractTask, tasks.AbstractSwingup):
        assert inspect.isabstract(cls) or cls.__abstractvars__ or cls.__abstractclassvars__
    built = {Acrobot: Acrobot.rods(), Cartpole: Cartpole.rods(), DoubleCartpole: DoubleCartpole.rods(),
             ChainSwingup: ChainSwingup(chain), DiffRLCartpole: DiffRLCartpole.diffrl()}
    assert set(built) == set(FINAL)
    for cls, task in built.items():
        assert getattr(cls, "__final__", False) is True, cls
        assert not inspect.isabstract(cls) and not cls.__abstractvars__ and not cls.__abstractclassvars__
        assert isinstance(task, tasks.AbstractTask) and type(task) is cls
        assert not hasattr(task, "kind") and "name" not in {f.name for f in dataclasses.fields(cls)}
        assert isinstance(cls.name, str) and task.name == cls.name
        assert not any(f.type in (str, "str") and f.name != "bodies" for f in dataclasses.fields(cls)), cls
    assert issubclass(DiffRLCartpole, tasks.AbstractTask) and not issubclass(DiffRLCartpole, tasks.AbstractSwingup)
    assert all(issubclass(c, tasks.AbstractSwingup) for c in (Acrobot, Cartpole, DoubleCartpole, ChainSwingup))
    assert (ChainSwingup.name, DiffRLCartpole.name) == ("chain", "diffrl_cartpole")


def test_reset_draws_by_hand():
    """The reset's random draws, written out: the noise from ``split(key)``, the start row from
    ``fold_in(key, 0x5A)``, the ``upright`` coin from ``fold_in(key, 0x0B)`` (each its own key, so adding one leaves
    the others' draws as they were)."""
    X = jnp.asarray(np.random.default_rng(0).normal(size=(5, 6)))
    task = DoubleCartpole.rods(starts=X, upright=0.4, noise=0.05)
    for seed in range(20):
        key = jax.random.PRNGKey(seed)
        kq, kv = jax.random.split(key)
        q = jax.random.uniform(kq, (3,), jnp.float64, -0.05, 0.05)
        qd = jax.random.uniform(kv, (3,), jnp.float64, -0.05, 0.05)
        row = X[jax.random.randint(jax.random.fold_in(key, 0x5A), (), 0, 5)]
        if jax.random.bernoulli(jax.random.fold_in(key, 0x0B), 0.4):
            want_q, want_qd = q + jnp.array([0.0, jnp.pi, 0.0]), qd
        else:
            want_q, want_qd = q + row[:3], qd + row[3:]
        got = task.reset(key)
        np.testing.assert_array_equal(got.q, want_q) and np.testing.assert_array_equal(got.qd, want_qd)


def test_chain_task_is_the_acrobot_on_the_acrobot_chain():
    """``ChainSwingup`` on the acrobot's chain resets, steps, observes and rewards exactly as ``Acrobot``."""
    a, c = Acrobot.rods(trig=True, upright=0.3), ChainSwingup(systems.acrobot(), trig=True, upright=0.3)
    keys = jax.random.split(jax.random.PRNGKey(4), 64)
    u = jnp.full((64, 1), 0.7)

    @jax.jit
    def both(keys, u):  # each task's reset, step, observation and reward: one compiled program
        out = []
        for task in (a, c):
            s = jax.vmap(task.reset)(keys)
            n = jax.vmap(task.step)(s, u)
            out.append((s.q, n.qd, jax.vmap(task.observe)(n), jax.vmap(task.reward)(s, u, n)))
        return out

    for x, y in zip(*both(keys, u)):  # reset q, next qd, observation, reward
        np.testing.assert_array_equal(x, y)


def test_chain_task_validates():
    cart = lg.systems.cartpole()
    with pytest.raises(ValueError, match="ChainSwingup needs revolute joints only"):
        ChainSwingup(cart)
    with pytest.raises(ValueError, match="ChainSwingup needs an actuated chain"):
        ChainSwingup(Chain([Link("revolute", 1.0, 1.0)]))
    pendulum = lg.systems.pendulum(gear=5.0)
    for field, value in (("noise", -0.1), ("horizon", 0), ("horizon", 2.5), ("substeps", 0), ("dt", 0.0)):
        with pytest.raises(ValueError, match=f"ChainSwingup.{field} must be"):
            ChainSwingup(pendulum, **{field: value})


def test_paper_tasks_check_their_chain():
    """A paper task on a chain of the wrong shape is refused, naming the joints it needs."""
    with pytest.raises(ValueError, match=r"Acrobot.chain must have the joints \('revolute', 'revolute'\)"):
        Acrobot(systems.cartpole())
    with pytest.raises(ValueError, match="Cartpole.chain must have the joints"):
        Cartpole(systems.double_cartpole())
    with pytest.raises(ValueError, match="DoubleCartpole.chain must have the joints"):
        DoubleCartpole(systems.cartpole())
    with pytest.raises(ValueError, match="Acrobot.chain must be actuated"):
        Acrobot(systems.acrobot(gear=None))


def test_trig_observation_is_continuous_through_hanging():
    a = dataclasses.replace(Acrobot.rods(), trig=True)
    assert bool(eqx.tree_equal(a, Acrobot.rods(trig=True)))
    left, right = _state([-1e-6, 0.2], [1.0, 0.0]), _state([1e-6, 0.2], [1.0, 0.0])
    np.testing.assert_allclose(a.observe(left), a.observe(right), atol=1e-5)
    paper = Acrobot.rods()
    assert abs(float(paper.observe(left)[0] - paper.observe(right)[0])) > 6.28  # the wrapped angle jumps by 2 pi
    s = _state([np.pi + 0.3, -0.2], [1.0, -2.0])
    np.testing.assert_allclose(a.observe(s), [np.sin(0.3), np.sin(-0.2), np.cos(0.3), np.cos(-0.2), 1.0, -2.0],
                               atol=1e-12)
    assert a.observation_size == 6


def test_step_takes_one_state_and_one_action():
    """A task's step takes one state and an action of shape (m,), refusing another shape by name (a (1, 1) action
    once turned the state into a batch); batches go through ``jax.vmap``; an integer action is converted."""
    task = Acrobot.rods()
    s = task.reset(jax.random.PRNGKey(0))
    for bad, shape in ((jnp.array([[0.3]]), r"\(1, 1\)"), (jnp.array(0.3), r"\(\)"), (jnp.zeros(2), r"\(2,\)")):
        with pytest.raises(ValueError, match=rf"Acrobot\.step: action must have shape \(m,\) = \(1,\), one entry per "
                                             rf"actuated joint, got {shape}; jax\.vmap the step"):
            task.step(s, bad)
    with pytest.raises(ValueError, match=r"Acrobot\.step: state\.q and state\.qd must have shape \(n,\) = \(2,\), got "
                                         r"\(1, 2\) and \(1, 2\)"):
        task.step(TaskState(s.q[None], s.qd[None]), jnp.array([0.3]))
    with pytest.raises(TypeError, match=r"Acrobot\.step: action must hold real numbers in \[-1, 1\], got dtype bool"):
        task.step(s, jnp.array([True]))
    states = TaskState(jnp.stack([s.q, s.q]), jnp.stack([s.qd, s.qd]))
    batch = jax.jit(jax.vmap(lambda s, a: task.step(s, a)))(states, jnp.array([[0.3], [1.0]]))
    one = jax.jit(lambda s, a: task.step(s, a))
    np.testing.assert_allclose(batch.q[1], one(s, jnp.array([1.0])).q, rtol=1e-14, atol=1e-15)
    assert states_equal(one(s, jnp.array([1])), one(s, jnp.array([1.0])))



def test_fields_and_states_of_the_wrong_kind_are_refused_by_name():
    """A bool or a string where a number belongs (``dt=True`` was one second), a string for ``trig``, a solver by
    name, no chain, and a batch or a tuple where one ``TaskState`` belongs (``observe`` and ``reward`` once read a
    batch silently); ``balanced`` and ``upright_error`` check their arguments."""
    refused = [
        (lambda: Acrobot.rods(dt=True), ValueError, r"Acrobot\.dt must be a number in \(0, inf\), got True"),
        (lambda: Acrobot.rods(dt="0.01"), ValueError, r"Acrobot\.dt must be a number in \(0, inf\), got '0\.01'"),
        (lambda: Acrobot.rods(upright="0.5"), ValueError, r"Acrobot\.upright must be a number in \[0, 1\]"),
        (lambda: Cartpole.rods(noise=True), ValueError, r"Cartpole\.noise must be a number in \[0, inf\)"),
        (lambda: Acrobot.rods(trig="yes"), ValueError, r"Acrobot\.trig must be True or False, got 'yes'"),
        (lambda: Acrobot.rods(solver="rk4"), TypeError, r"Acrobot\.solver must be one of lagrange\.RK4\(\)"),
        (lambda: DiffRLCartpole.diffrl(noise_q=-1.0), ValueError, r"DiffRLCartpole\.noise_q must be a number in \[0"),
        (lambda: Acrobot(None), TypeError,
         r"Acrobot\.chain must be a lagrange\.Tree \(a lagrange\.chain\.Chain is one\), got NoneType"),
        (lambda: ChainSwingup("chain"), TypeError,
         r"ChainSwingup\.chain must be a lagrange\.Tree \(a lagrange\.chain\.Chain is one\), got str"),
    ]
    task = Acrobot.rods()
    s = task.reset(jax.random.PRNGKey(0))
    batch = TaskState(jnp.stack([s.q, s.q]), jnp.stack([s.qd, s.qd]))
    diffrl = DiffRLCartpole.diffrl()
    refused += [
        (lambda: task.observe(batch), ValueError, r"Acrobot: state\.q and state\.qd must have shape \(n,\) = \(2,\)"),
        (lambda: task.reward(s, jnp.zeros(1), batch), ValueError, r"got \(2, 2\) and \(2, 2\); jax\.vmap"),
        (lambda: diffrl.observe(batch), ValueError, r"DiffRLCartpole\.observe: state\.q and state\.qd must have"),
        (lambda: task.step((s.q, s.qd), jnp.zeros(1)), TypeError, r"Acrobot\.step: state must be a .*TaskState"),
        (lambda: tasks.balanced(task, jnp.zeros((10, 2)), fraction=0.0), ValueError, r"fraction must be a number in"),
        (lambda: tasks.balanced(task, jnp.zeros((10, 2)), tolerance=-1.0), ValueError, r"tolerance must be a number"),
        (lambda: tasks.balanced(task, jnp.zeros(2)), ValueError, r"balanced: q must have shape \(\.\.\., T, n = 2\)"),
        (lambda: tasks.upright_error(task, jnp.zeros((5, 3))), ValueError, r"q must have shape \(\.\.\., n = 2\)"),
    ]
    for make, error, message in refused:
        with pytest.raises(error, match=message):
            make()
