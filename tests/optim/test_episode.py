"""Rollouts (optim/episode.py): an episode is the task's reset, then the policy and the task's step, observation and
reward applied step by step (checked against those calls made one at a time, with a recurrent policy whose hidden
state starts at zero and a normaliser that is not the identity); truncated BPTT keeps the values and cuts the
gradient (a window of one step against the gradient of each step's reward alone); ``evaluate`` is the batch of
episodes from split keys with ``lagrange.tasks.balanced`` of each."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import optim
from lagrange.tasks import TaskState, balanced
from policies import GRUPolicy, MLPPolicy, Normalizer
from tests.helpers import pendulum_swingup

T = 20


def _normalizer(size):
    """A normaliser that shifts and scales (not the identity), so that a rollout that skipped it would differ."""
    return Normalizer(jnp.linspace(0.3, -0.2, size), jnp.linspace(0.5, 2.0, size), jnp.asarray(10.0))


def test_episode_is_the_tasks_steps_one_at_a_time():
    task = pendulum_swingup(horizon=T, noise=0.5)
    policy = GRUPolicy.for_task(task, width=8, key=jax.random.PRNGKey(1))
    norm = _normalizer(task.observation_size)
    key = jax.random.PRNGKey(2)
    ep = jax.jit(lambda k: optim.episode(task, policy, norm, k))(key)
    n = task.chain.nv
    assert ep.rewards.shape == (T,) and ep.obs.shape == (T, task.observation_size)
    assert ep.actions.shape == (T, task.action_size) and ep.q.shape == ep.qd.shape == (T + 1, n)
    s0 = task.reset(key)
    np.testing.assert_array_equal(ep.q[0], s0.q)
    np.testing.assert_array_equal(ep.qd[0], s0.qd)

    @jax.jit
    def one_step(q, qd, hidden, t):
        s = TaskState(q, qd)
        obs = task.observe(s)
        a, hidden = policy(norm(obs), hidden, t == 0)
        s2 = task.step(s, a)
        return obs, a, s2, task.reward(s, a, s2), hidden

    hidden = jnp.full(policy.hidden_size, 7.0)  # garbage: the reset at t = 0 must replace it by zeros
    for t in range(T):
        obs, a, s2, r, hidden = one_step(ep.q[t], ep.qd[t], hidden, t)
        # each step recomputed from the recorded state: float64 round-off of one RK4 step and one GRU call
        np.testing.assert_allclose(ep.obs[t], obs, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(ep.actions[t], a, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(ep.q[t + 1], s2.q, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(ep.qd[t + 1], s2.qd, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(ep.rewards[t], r, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(ep.ret, np.sum(ep.rewards), rtol=1e-14)
    assert float(np.ptp(np.asarray(ep.actions))) > 0.01  # actions that vary (measured spread 0.037): the check can fail


def test_truncation_keeps_the_values_and_cuts_the_gradient():
    """With ``truncation = 1`` the state and hidden state are cut after every step, so the gradient of the return is
    the sum over steps of the gradient of that step's reward through its own action only, from the recorded state;
    with ``truncation >= horizon`` nothing inside the episode is cut."""
    task = pendulum_swingup(horizon=T, noise=0.5)
    policy = MLPPolicy.for_task(task, width=8, depth=1, key=jax.random.PRNGKey(3))
    norm = _normalizer(task.observation_size)
    key = jax.random.PRNGKey(4)
    flat, unravel = optim.flatten_policy(policy)

    def ret(p, truncation):
        return optim.episode(task, unravel(p), norm, key, truncation=truncation).ret

    # the three truncations (each its own program inside), the episode and the gradient of its per-step rewards from
    # the recorded states: one compilation
    @jax.jit
    def everything(p):
        ep = optim.episode(task, policy, norm, key)

        def per_step(p):
            def r(q, qd):
                s = TaskState(q, qd)
                a, _ = unravel(p)(norm(task.observe(s)), jnp.zeros(0), False)
                return task.reward(s, a, task.step(s, a))
            return jnp.sum(jax.vmap(r)(ep.q[:-1], ep.qd[:-1]))

        return ([jax.value_and_grad(lambda p: ret(p, truncation))(p) for truncation in (None, 1, T)],
                jax.grad(per_step)(p))

    ((full, g_full), (one, g_one), (whole, g_whole)), g_per_step = everything(flat)
    assert float(one) == float(full) == float(whole)  # the values are untouched, bit for bit
    np.testing.assert_allclose(g_whole, g_full, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(g_one, g_per_step, rtol=1e-11, atol=1e-12)
    assert float(jnp.max(jnp.abs(g_one - g_full))) > 1e-3 * float(jnp.max(jnp.abs(g_full)))  # the cut matters


def test_evaluate_is_the_batch_of_episodes():
    task = pendulum_swingup(horizon=T, noise=0.5)
    policy = GRUPolicy.for_task(task, width=8, key=jax.random.PRNGKey(5))
    key = jax.random.PRNGKey(6)
    rets, bal = jax.jit(lambda k: optim.evaluate(task, policy, None, k, 3))(key)
    assert rets.shape == bal.shape == (3,) and bal.dtype == bool
    one = jax.jit(lambda k: optim.episode(task, policy, None, k))
    for i, k in enumerate(jax.random.split(key, 3)):
        ep = one(k)
        np.testing.assert_allclose(rets[i], ep.ret, rtol=1e-12)
        assert bool(bal[i]) == bool(balanced(task, ep.q))
    assert len(set(np.asarray(rets).tolist())) == 3  # three different starts
    # a balance task held by the zero action for these 20 steps of 0.05 s from within 0.01 rad: balanced
    up = pendulum_swingup(horizon=T, upright=1.0)
    zero = MLPPolicy.for_task(up, width=2, depth=0)
    zero = jax.tree_util.tree_map(lambda x: jnp.zeros_like(x) if isinstance(x, jax.Array) else x, zero)
    _, bal_up = optim.evaluate(up, zero, None, key, 3)
    assert bool(jnp.all(bal_up)) and not bool(jnp.any(bal))
    with pytest.raises(ValueError, match=r"evaluate: episodes must be an integer >= 1, got 0"):  # was a NaN mean
        optim.evaluate(task, policy, None, key, 0)
