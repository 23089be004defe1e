"""SHAC's losses (optim/shac/losses.py), each against an independent computation: TD(lambda) targets against the
explicit lambda-weighted sum of n-step returns, the window loss against its definition computed by a plain Python
loop, and the gradient cuts (at the window start, and at a reset) against a decomposition of the window."""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lagrange.tasks import TaskState
from optim import shac
from policies import Actor, Critic
from tests.helpers import pendulum_swingup


def _n_step_lambda_return(r, v, done, gamma, lam, t):
    """(1 - lam) sum_{n<k} lam^(n-1) G^(n) + lam^(k-1) G^(k), k = steps to the next end (inclusive)."""
    T = len(r)
    end = next(j for j in range(t, T) if done[j] or j == T - 1)
    k = end - t + 1

    def G(n):  # n-step return from t: rewards t..t+n-1, bootstrap with V of the state step t+n-1 lands in
        return sum(gamma**i * r[t + i] for i in range(n)) + gamma**n * v[t + n - 1]

    return (1 - lam) * sum(lam ** (n - 1) * G(n) for n in range(1, k)) + lam ** (k - 1) * G(k)


def test_td_lambda_targets_match_the_lambda_weighted_n_step_returns():
    rng = np.random.default_rng(0)
    T, N, gamma, lam = 9, 3, 0.99, 0.95
    r = rng.normal(size=(T, N))
    v = rng.normal(size=(T, N))
    done = np.zeros((T, N), bool)
    done[3, 0] = True  # an episode ends inside the window for env 0
    done[0, 2] = done[6, 2] = True
    got = np.asarray(shac.td_lambda_targets(jnp.asarray(r), jnp.asarray(v), jnp.asarray(done), gamma, lam))
    want = np.array([[_n_step_lambda_return(r[:, j], v[:, j], done[:, j], gamma, lam, t) for j in range(N)]
                     for t in range(T)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    # lam = 0: one-step targets; lam = 1: Monte-Carlo returns bootstrapped at the window end.
    np.testing.assert_allclose(shac.td_lambda_targets(r, v, done, gamma, 0.0), r + gamma * v, rtol=1e-13)


_H = 6  # window length of the loss tests


def _setup(noise=0.0):
    task = pendulum_swingup(horizon=10, noise=noise)
    k = jax.random.split(jax.random.PRNGKey(3), 3)
    # log_std = -1000: exp underflows to exactly 0, so the actor's actions are deterministic.
    actor = Actor(2, 1, (8,), init_log_std=-1000.0, key=k[0])
    critic = Critic(2, (8,), key=k[1])
    env = jax.vmap(task.reset)(jax.random.split(k[2], 3))
    env = TaskState(env.q + jnp.array([2.5]), env.qd + jnp.array([-1.0]))
    return task, actor, critic, env


def _loss(actor, critic, task, env, progress, h, key=jax.random.PRNGKey(7)):
    return shac.actor_loss(actor, critic, None, task, env, progress, jnp.zeros(progress.shape), key,
                           short_horizon=h, horizon=task.horizon, gamma=0.99)


@functools.cache
def _windows():
    """The window loss with the critic and without (``target_critic=None``), the window, and the loss's definition by a
    plain Python loop (its reward part and its critic part per environment), for the two tests below: one compiled
    program."""
    task, actor, critic, env = _setup()
    prog = jnp.zeros(3, jnp.int32)

    @jax.jit
    def windows(env):
        rets, tails = [], []
        for j in range(3):
            s = TaskState(env.q[j], env.qd[j])
            ret = 0.0
            for t in range(_H):
                a = actor.deterministic(task.observe(s))
                s2 = task.step(s, a)
                ret += 0.99**t * task.reward(s, a, s2)
                s = s2
            rets.append(ret)
            tails.append(0.99**_H * critic(task.observe(s)))
        return (_loss(actor, critic, task, env, prog, _H), _loss(actor, None, task, env, prog, _H)[0], rets, tails)

    return windows(env)


def test_window_loss_matches_its_definition():
    """No episode ends: -(sum_t gamma^t r_t + gamma^h V(s_h)) averaged over envs, divided by h."""
    (loss, win), _, rets, tails = _windows()
    want = 0.0
    for ret, tail in zip(rets, tails):
        want += -(float(ret) + float(tail))
    np.testing.assert_allclose(float(loss), want / (_H * 3), rtol=1e-12)
    assert not bool(win.dones.any())


def test_bptt_window_loss_is_the_discounted_return_alone():
    """Without a critic (``target_critic=None``: the authors' BPTT), the loss is minus the window's discounted reward,
    nothing added at its end: the SHAC loss with the critic's term taken away."""
    (with_critic, _), loss, rets, tails = _windows()
    want, tail = 0.0, 0.0
    for r, v in zip(rets, tails):
        want -= float(r)
        tail -= float(v)
    ret, tail = want / (_H * 3), tail / (_H * 3)
    np.testing.assert_allclose(float(loss), ret, rtol=1e-12)
    np.testing.assert_allclose(float(with_critic) - float(loss), tail, rtol=1e-9)
    assert abs(float(tail)) > 1e-3  # the critic's term is there to be taken away


def test_gradient_is_cut_at_the_window_start():
    """The loss does not depend, through the gradient, on how the window's start state was reached."""
    task, actor, critic, env = _setup()

    def uncut(e):  # the same loss without the cut
        s, ret = TaskState(e.q[0], e.qd[0]), 0.0
        for t in range(_H):
            a = actor.deterministic(task.observe(s))
            s2 = task.step(s, a)
            ret = ret + 0.99**t * task.reward(s, a, s2)
            s = s2
        return -ret

    def cut(e):
        return _loss(actor, critic, task, e, jnp.zeros(3, jnp.int32), _H)[0]

    g, g_uncut = jax.jit(lambda e: (jax.grad(cut)(e), jax.grad(uncut)(e)))(env)  # both gradients: one compilation
    for leaf in jax.tree_util.tree_leaves(g):
        assert np.all(np.asarray(leaf) == 0.0)  # exactly zero
    # ... while the same loss without the cut does depend on it (the test can fail).
    assert float(jnp.abs(g_uncut.q).max()) > 1e-3


def test_gradient_through_a_reset_is_zero():
    """An episode that ends at step k of the window splits it into two independent windows: the loss and
    its actor gradient equal those of the window before the reset plus the window after it (the reset
    state being the task's deterministic reset, noise 0), so no gradient crosses the reset."""
    task, actor, critic, env = _setup(noise=0.0)
    k = 2
    progress = jnp.full(3, task.horizon - k, jnp.int32)  # every episode ends after k steps

    def full(act):
        return _loss(act, critic, task, env, progress, _H)[0] * (_H * 3)

    def before(act):  # the k steps up to the episode end, bootstrapped with V of the last state
        return _loss(act, critic, task, env, progress, k)[0] * (k * 3)

    def after(act):  # the h - k steps from the reset state
        fresh = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), 3))
        return _loss(act, critic, task, fresh, jnp.zeros(3, jnp.int32), _H - k)[0] * ((_H - k) * 3)

    @eqx.filter_jit
    def everything(act):  # one compilation for the three losses, their gradients and the window
        return ([eqx.filter_value_and_grad(f)(act) for f in (full, before, after)],
                _loss(act, critic, task, env, progress, _H)[1])

    ((v_full, g_full), (v_before, g_before), (v_after, g_after)), win = everything(actor)
    assert np.asarray(win.dones)[k - 1].all() and not np.asarray(win.dones)[k:].any()
    np.testing.assert_allclose(float(v_full), float(v_before) + float(v_after), rtol=1e-12)
    g_sum = jax.tree_util.tree_map(lambda a, b: a + b, g_before, g_after)
    for a, b in zip(jax.tree_util.tree_leaves(g_full), jax.tree_util.tree_leaves(g_sum)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
    assert max(float(jnp.abs(x).max()) for x in jax.tree_util.tree_leaves(g_full)) > 1e-6  # not trivially zero
