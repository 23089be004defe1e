"""The APG inner step (optim/bptt.py): ``apg_steps`` is a hand-written loop of Adam steps on the gradient of an
objective of a batch of episodes, for the default objective (minus the mean return) and for a custom one (minus the
mean of the last 10 rewards), which gives other gradients, and with its gradients clipped to a global norm; it reports
each step's gradient norm; a non-finite objective freezes the parameters and says so; ``flatten_policy`` round-trips a
module."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import optim
from policies import GRUPolicy, MLPPolicy, Normalizer
from tests.helpers import pendulum_swingup

STEPS, EPISODES, LR = 3, 2, 1e-2


def last_ten(episodes):
    """A custom objective: minus the mean reward of the last 10 steps (how well the episodes end)."""
    return -jnp.mean(episodes.rewards[:, -10:])


@pytest.fixture(scope="module")
def problem():
    task = pendulum_swingup(horizon=20, noise=0.5)
    policy = MLPPolicy.for_task(task, width=4, depth=1, key=jax.random.PRNGKey(1))
    params, unravel = optim.flatten_policy(policy)
    return task, params, unravel, Normalizer.create(task.observation_size), jax.random.PRNGKey(2)


_CACHE = {}


def _cached(f):
    """Results kept per objective and options, so that the tests share their compilations."""
    def cached(problem, *args, **kw):
        k = (f.__name__, args, tuple(sorted(kw.items())))
        if k not in _CACHE:
            _CACHE[k] = f(problem, *args, **kw)
        return _CACHE[k]
    return cached


@_cached
def _value_and_grad(problem, objective):
    """The jitted objective of step ``i``'s batch and its gradient (one compilation per objective, whatever the
    clip)."""
    task, params, unravel, norm, key = problem

    @jax.jit
    def value_and_grad(p, norm, i):
        keys = jax.random.split(jax.random.fold_in(key, i), EPISODES)

        def loss(p):
            eps = jax.vmap(lambda k: optim.episode(task, unravel(p), norm, k))(keys)
            return objective(eps), eps.obs

        return jax.value_and_grad(loss, has_aux=True)(p)

    return value_and_grad


@_cached
def _by_hand(problem, objective, clip=None):
    """The loop ``apg_steps`` documents, one jitted gradient per step: the gradient of each step (before clipping to
    the global norm ``clip``, where given) and the results."""
    task, params, unravel, norm, key = problem
    value_and_grad = _value_and_grad(problem, objective)
    adam = optax.scale_by_adam()
    opt, p, grads, values = adam.init(params), params, [], []
    for i in range(STEPS):
        (value, obs), g = value_and_grad(p, norm, i)
        norm_g = float(np.sqrt(np.sum(np.asarray(g) ** 2)))
        upd, opt = adam.update(g if clip is None else g * min(1.0, clip / norm_g), opt)
        p = p - LR * upd
        norm = norm.update(obs)
        grads.append(g)
        values.append(-value)
    return p, norm, np.asarray(values), grads, opt


@_cached
def _apg(problem, **kw):
    task, params, unravel, norm, key = problem
    return jax.jit(lambda p: optim.apg_steps(task, unravel, p, norm, key, steps=STEPS, episodes=EPISODES,
                                             learning_rate=LR, **kw))(params)


@pytest.mark.parametrize("objective", [None, last_ten], ids=["default", "last_ten"])
def test_apg_steps_is_the_hand_written_loop(problem, objective):
    res = _apg(problem) if objective is None else _apg(problem, objective=objective)
    p, norm, values, grads, opt = _by_hand(problem, objective or optim.mean_return_loss)
    # the same operations in a scan instead of a Python loop: float64 round-off only (measured 6e-17 on the
    # parameters, 0 on the returns)
    np.testing.assert_allclose(res.params, p, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(res.returns, values, rtol=1e-12)
    for a, b in zip(jax.tree_util.tree_leaves((res.normalizer, res.opt_state)), jax.tree_util.tree_leaves((norm, opt))):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)
    assert bool(res.finite) and float(res.normalizer.count) == STEPS * EPISODES * 20
    np.testing.assert_allclose(res.grad_norms, [np.linalg.norm(g) for g in grads], rtol=1e-12)


def test_max_grad_norm_clips_the_gradient_adam_sees(problem):
    """``max_grad_norm`` rescales a gradient longer than it to that norm before Adam: the hand-written loop with the
    rescaling, and the reported norms are those before clipping. A bound above every norm changes nothing; a bound <= 0
    is refused."""
    _, params, _, _, _ = problem
    norms = np.asarray(_apg(problem).grad_norms)
    clip = float(np.min(norms)) / 2  # every step is clipped (norms measured 83-111)
    res = _apg(problem, max_grad_norm=clip)
    p, norm, values, grads, opt = _by_hand(problem, optim.mean_return_loss, clip=clip)
    np.testing.assert_allclose(res.params, p, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(res.returns, values, rtol=1e-12)
    np.testing.assert_allclose(res.grad_norms, [np.linalg.norm(g) for g in grads], rtol=1e-12)
    assert float(jnp.max(jnp.abs(res.params - _apg(problem).params))) > 1e-6  # clipping moved the run
    loose = _apg(problem, max_grad_norm=float(np.max(norms)) * 2)
    # a factor of exactly 1 in another compiled program: the same up to XLA's float64 round-off
    np.testing.assert_allclose(loose.params, _apg(problem).params, rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="max_grad_norm"):
        optim.apg_steps(None, None, params, None, None, steps=1, episodes=1, learning_rate=1.0,
                        max_grad_norm=0.0)
    for name in ("steps", "episodes"):  # zero steps was a silent no-op, zero episodes a NaN return
        with pytest.raises(ValueError, match=rf"apg_steps: {name} must be an integer >= 1, got 0"):
            optim.apg_steps(None, None, params, None, None, **{"steps": 1, "episodes": 1, name: 0}, learning_rate=1.0)


def test_the_objective_changes_the_gradient(problem):
    """The last-10-rewards objective is not the mean return: other gradients, other parameters; the default
    objective's reported returns are the batches' mean returns."""
    *_, g_default, _ = _by_hand(problem, optim.mean_return_loss)
    *_, g_last, _ = _by_hand(problem, last_ten)
    cos = float(jnp.dot(g_default[0], g_last[0]) / (jnp.linalg.norm(g_default[0]) * jnp.linalg.norm(g_last[0])))
    assert cos < 0.999  # not parallel (measured cosine 0.984); a proportional objective would give 1 - 1e-15
    default, custom = _apg(problem), _apg(problem, objective=last_ten)
    assert float(jnp.max(jnp.abs(default.params - custom.params))) > 1e-3  # measured 0.037
    task, params, unravel, norm, key = problem
    eps = jax.vmap(lambda k: optim.episode(task, unravel(params), norm, k))(jax.random.split(jax.random.fold_in(key, 0),
                                                                                            EPISODES))
    np.testing.assert_allclose(default.returns[0], jnp.mean(eps.ret), rtol=1e-12)
    np.testing.assert_allclose(custom.returns[0], jnp.mean(eps.rewards[:, -10:]), rtol=1e-12)


def nan_objective(episodes):
    return jnp.mean(episodes.ret) * jnp.nan


def test_nonfinite_objective_freezes_the_parameters(problem):
    """An objective that is NaN from the first step: no update is taken, the normaliser is kept, ``finite`` is
    false; ``update_normalizer=False`` keeps the normaliser of a finite run."""
    _, params, _, norm, _ = problem
    res = _apg(problem, objective=nan_objective)
    assert not bool(res.finite)
    np.testing.assert_array_equal(res.params, params)
    assert float(res.normalizer.count) == 0.0
    frozen = _apg(problem, update_normalizer=False)
    assert bool(frozen.finite) and float(frozen.normalizer.count) == 0.0
    assert not np.array_equal(frozen.params, params)


def test_flatten_policy_round_trips():
    task = pendulum_swingup()
    policy = GRUPolicy.for_task(task, width=4, key=jax.random.PRNGKey(0))
    flat, unravel = optim.flatten_policy(policy)
    leaves = jax.tree_util.tree_leaves(policy)
    assert flat.shape == (sum(x.size for x in leaves),)
    back = unravel(flat)
    assert type(back) is GRUPolicy and back.hidden_size == policy.hidden_size
    for a, b in zip(jax.tree_util.tree_leaves(back), leaves):
        np.testing.assert_array_equal(a, b)
    moved = unravel(flat + 1.0)
    np.testing.assert_array_equal(moved.head.bias, policy.head.bias + 1.0)
