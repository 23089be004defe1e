"""DFlex's Hopper and Cheetah (``lagrange.tasks.Hopper.diffrl``, ``Cheetah.diffrl``): the bodies as DFlex's loader
builds them (masses, centres of mass and inertias recomputed independently from its capsule formula on the SHAC
release's assets: torso 3.665191, thigh 4.057891, leg 2.781357, foot 5.315575 kg; the cheetah's 21.1837 kg), the
assembled tree (M's translational block is the total mass plus armature, the foot 4 cm above the ground at rest),
the reward, the early end, the reset noise; episodes that end early count nothing after (``optim.episode``), and SHAC
values an early end at 0 where it bootstraps a time limit."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
import optim
from lagrange.planar.lower import lower as planar
from lagrange.tasks import Cheetah, Hopper, TaskState
from lagrange.tasks.locomotion import DFLEX_SOLVER, capsule_mass_and_inertia
from optim.shac.losses import actor_loss
from policies import Actor, Critic


def test_the_bodies_are_dflex_s():
    hopper, cheetah = Hopper.diffrl().chain, Cheetah.diffrl().chain
    np.testing.assert_allclose(np.asarray(hopper.mass), [0, 0, 3.665191, 4.057891, 2.781357, 5.315575], atol=1e-6)
    np.testing.assert_allclose(np.asarray(planar(hopper).inertia)[2:], [0.069246, 0.093299, 0.072303, 0.103523],
                               atol=1e-6)
    np.testing.assert_allclose(np.asarray(cheetah.mass)[2:], [9.457333, 2.335527, 2.402003, 1.657471, 2.175984,
                                                              1.817013, 1.338385], atol=1e-6)
    np.testing.assert_allclose(np.asarray(planar(cheetah).inertia)[2:], [1.357449, 0.025488, 0.027641, 0.009612,
                                                                         0.020790, 0.012441, 0.005340], atol=1e-6)
    assert abs(float(jnp.sum(cheetah.mass)) - 21.1837) < 1e-3
    # the torso's centre of mass (DFlex: (0.152390, 0.025398) in the torso's frame)
    lowered = planar(cheetah)
    assert abs(float(lowered.com_normal[2]) - 0.152390) < 1e-6 and abs(float(-lowered.com[2]) - 0.025398) < 1e-6
    m, i = capsule_mass_and_inertia(0.05, 0.4)
    assert abs(m - 3.665191) < 1e-6 and abs(i - 0.069246) < 1e-6
    assert cheetah.parents == (-1, 0, 1, 2, 3, 4, 2, 6, 7) and planar(hopper).serial
    assert len(planar(hopper).contact_links) == 8 and len(planar(cheetah).contact_links) == 16


@pytest.mark.parametrize("make, total, armature", [(Hopper.diffrl, 15.820014, 1.0), (Cheetah.diffrl, 21.183716, 0.1)])
def test_the_tree_is_assembled(make, total, armature):
    """At any pose the x slide moves every mass: M[0, 0] = total mass + armature; gravity's pull on the z slide is the
    total weight; at rest the lowest contact spot is where DFlex puts it."""
    task = make()
    q = jax.random.uniform(jax.random.PRNGKey(0), (task.chain.nq,), minval=-0.5, maxval=0.5)

    @jax.jit
    def terms(q, start):  # one compiled program (op by op, each operation is a compilation)
        return (lg.mass_matrix(task.chain, q), lg.gravity_forces(task.chain, q),
                lg.kinematics.contact_point_positions(task.chain, start))

    M, gravity, pts = terms(q, jnp.asarray(task.start))
    assert abs(float(M[0, 0]) - (total + armature)) < 1e-4 and abs(float(M[1, 1]) - (total + armature)) < 1e-4
    assert abs(float(gravity[1]) - 9.81 * total) < 1e-3
    lowest = float(jnp.min(pts[:, 2] - planar(task.chain).contact_points[:, 2]))  # z - radius
    assert abs(lowest - (0.04 if task.name == "hopper" else 0.1759)) < 1e-3, lowest


def test_hopper_reward_and_early_end():
    task = Hopper.diffrl()
    z = jnp.zeros(6)
    rest = TaskState(z, z)
    # at its start height: h = clip(0 + 0.30, -1, 0.3) = 0.3, upright, no motion, no action
    assert abs(float(task.reward(rest, jnp.zeros(3), rest)) - 1.3) < 1e-6
    low = TaskState(z.at[1].set(-0.5).at[2].set(0.2), z.at[0].set(1.5))
    h = -0.2  # -0.5 + 0.30
    expected = 1.5 - 200 * h * h + 1 - (0.2 / (np.pi / 6)) ** 2 - 0.1 * (1 + 1 + 0.25)
    assert abs(float(task.reward(rest, jnp.array([1.0, -3.0, 0.5]), low)) - expected) < 1e-4  # a clipped to [-1, 1]
    assert bool(task.terminated(low)) and not bool(task.terminated(rest))
    assert not bool(Cheetah.diffrl().terminated(TaskState(jnp.full(9, -5.0), jnp.zeros(9))))


@pytest.mark.parametrize("make, nq, nqd, start", [(Hopper.diffrl, 0.05, 0.05, 0.0), (Cheetah.diffrl, 0.1, 0.25, -0.2)])
def test_reset_noise(make, nq, nqd, start):
    task = make()

    @jax.jit
    def draw(key):  # 2000 resets and one observation: one compiled program
        s = jax.vmap(task.reset)(jax.random.split(key, 2000))
        return s, task.observe(TaskState(s.q[0], s.qd[0]))

    s, obs = draw(jax.random.PRNGKey(1))
    q = np.asarray(s.q) - np.asarray(task.start)
    assert np.all(np.abs(q) <= nq) and np.all(np.abs(np.asarray(s.qd)) <= nqd) and np.max(np.abs(q)) > 0.9 * nq
    assert task.start[1] == start and obs.shape == (2 * task.chain.nv - 1,)
    assert task.solver == DFLEX_SOLVER and task.dt == 1 / 60 and task.substeps == 16 and task.horizon == 1000


class Still(eqx.Module):
    """A policy that does nothing."""

    def initial_state(self):
        return jnp.zeros(0)

    def __call__(self, obs, hidden, reset):
        return jnp.zeros(3), hidden


def test_an_episode_that_ends_early_counts_nothing_after():
    """The hopper with no action falls: its rewards stop at the step that ended it and the state stays there."""
    task = Hopper.diffrl(horizon=300)

    @jax.jit
    def run(key):  # the episode and the early end at each of its states: one compiled program
        ep = optim.episode(task, Still(), None, key)
        return ep, jax.vmap(lambda q, qd: task.terminated(TaskState(q, qd)))(ep.q[1:], ep.qd[1:])

    ep, ended = run(jax.random.PRNGKey(0))
    ended = np.asarray(ended)
    first = int(np.argmax(ended))
    assert ended.any() and first < 299
    assert np.all(np.asarray(ep.rewards)[first + 1:] == 0) and float(ep.rewards[first]) != 0
    assert np.all(np.asarray(ep.q)[first + 1:] == np.asarray(ep.q)[first + 1])
    assert not bool(task.succeeded(ep.q))


def test_shac_values_an_early_end_at_zero():
    """In SHAC's window an episode that ends early is done and valued 0; one that runs on is valued by the target
    critic; both reset."""
    task = Hopper.diffrl(horizon=1000)
    n = 4
    actor = Actor.for_task(task, units=(8,))
    critic = Critic(task.observation_size, (8,), key=jax.random.PRNGKey(1))
    @jax.jit
    def window(key):  # the starts and the window: one compiled program
        s = jax.vmap(task.reset)(jax.random.split(key, n))
        s = TaskState(s.q.at[:2, 1].set(-0.44).at[:2, 2].set(1.2), s.qd.at[:2, 1].set(-3.0))  # two about to fall
        return actor_loss(actor, critic, None, task, s, jnp.zeros(n, jnp.int32), jnp.zeros(n), jax.random.PRNGKey(3),
                          short_horizon=8, horizon=1000, gamma=0.99)

    loss, win = window(jax.random.PRNGKey(2))
    done, nv = np.asarray(win.dones), np.asarray(win.next_values)
    assert done[:, :2].any() and not done[:, 2:].any() and np.isfinite(float(loss))
    assert np.all(nv[done] == 0) and np.all(nv[~done] != 0)
    assert np.all(np.asarray(win.progress)[:2] < 8)  # reset after the fall


def test_shac_configs_are_the_authors():
    h, c = optim.SHACConfig.hopper(), optim.SHACConfig.cheetah()
    assert (h.num_envs, h.iterations, h.actor_lr, h.critic_lr) == (256, 2000, 2e-3, 2e-4)
    assert (c.num_envs, c.iterations, c.actor_lr, c.critic_lr) == (64, 2000, 2e-3, 2e-3)
    assert h.iterations * h.env_steps_per_epoch() == 16_384_000 and c.iterations * c.env_steps_per_epoch() == 4_096_000


def test_the_adapters_report_an_early_end():
    """Brax's done and Gymnasium's terminated are the task's early end (PPO then values the fall at 0)."""
    from lagrange.interop.brax import BraxEnv
    from lagrange.interop.gymnasium import GymEnv

    task = Hopper.diffrl()
    low = Hopper.diffrl(termination_height=0.1)  # ends at once: the hopper starts at height 0 +- 0.05
    env, env_low = BraxEnv(task, terminate_at_horizon=False), BraxEnv(low, terminate_at_horizon=False)
    state = env.reset(jax.random.PRNGKey(0))
    assert float(env.step(state, jnp.zeros(3)).done) == 0.0
    assert float(env_low.step(state, jnp.zeros(3)).done) == 1.0
    for t, expected in ((task, False), (low, True)):
        gym_env = GymEnv(t)
        gym_env.reset(seed=0)
        _, _, terminated, truncated, _ = gym_env.step(np.zeros(3, np.float32))
        assert terminated == expected and not truncated


def test_a_task_that_cannot_end_early_traces_no_termination(monkeypatch):
    """The property whose loss cost the acrobot demo 20 % of its return (dc5b7bf): a rollout of a task that cannot end
    early (``ends_early`` False: every pole task, the cheetah) traces no termination logic at all. Masks that change no
    value still change XLA's fusion of the rollout and with it the round-off, which CE-APG's chaotic swing-up amplified
    into another training run (``examples/acrobot_swingup.py --quick``: 2534 -> 2040). The episode, SHAC's window loss
    and the Brax adapter must never call ``terminated`` on such a task, and must call it on the hopper. (Only traced:
    the policy, critic and states are shapes, ``eqx.filter_eval_shape``, so that nothing is computed.)"""
    from lagrange.interop.brax import BraxEnv
    from lagrange.tasks import Acrobot, Cheetah, DiffRLCartpole

    calls = []

    def spy(self, state):
        calls.append(type(self).__name__)
        return jnp.zeros((), bool)

    for cls in (Acrobot, DiffRLCartpole, Cheetah, Hopper):
        monkeypatch.setattr(cls, "terminated", spy)
    for task, expect in ((Acrobot.rods(horizon=5), False), (DiffRLCartpole.diffrl(horizon=5), False),
                         (Cheetah.diffrl(horizon=5), False), (Hopper.diffrl(horizon=5), True)):
        calls.clear()
        policy = eqx.filter_eval_shape(Actor.for_task, task, units=(4,))
        eqx.filter_make_jaxpr(lambda p, k: optim.episode(task, p, None, k))(policy, jax.random.PRNGKey(0))
        s = jax.eval_shape(lambda k: jax.vmap(task.reset)(jax.random.split(k, 2)), jax.random.PRNGKey(2))
        critic = eqx.filter_eval_shape(Critic, task.observation_size, (4,), key=jax.random.PRNGKey(1))
        eqx.filter_make_jaxpr(lambda p, c, s: actor_loss(p, c, None, task, s, jnp.zeros(2, jnp.int32), jnp.zeros(2),
                                                         jax.random.PRNGKey(3), short_horizon=2, horizon=5,
                                                         gamma=0.99))(policy, critic, s)
        env = BraxEnv(task)
        eqx.filter_make_jaxpr(lambda st: env.step(st, jnp.zeros(task.action_size)))(
            eqx.filter_eval_shape(env.reset, jax.random.PRNGKey(0)))
        assert bool(calls) == expect, (type(task).__name__, calls)
        assert type(task).ends_early == expect


def test_a_task_that_defines_terminated_must_say_it_ends_early():
    """A task class that overrides ``terminated`` without ``ends_early = True`` is refused when it is defined (its
    rollouts would never look at ``terminated``)."""
    from lagrange.tasks import AbstractTask

    with pytest.raises(TypeError, match="defines terminated but not ends_early = True"):
        type("Falls", (AbstractTask,), {"terminated": lambda self, state: jnp.ones((), bool)})
