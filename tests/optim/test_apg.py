"""APG (optim/apg.py): it reaches a stated return (595 of 600) balancing a pendulum in 4 small iterations through
``optim.train``, and its checkpoint gives the state back; an iteration is one ``apg_steps`` call that continues from
the previous iteration's Adam state; it has one policy."""

import jax
import numpy as np
import pytest

import optim
from policies import GRUPolicy
from tests.helpers import RUN_KEY, pendulum_swingup, states_equal


def _balance_task():
    # a 1 kg, 1 m pendulum that starts within 0.3 rad (and 0.3 rad/s) of upright; torque 5 a N m.
    # Untrained GRU: about 420; zero torque: about 500; a hand-tuned PD controller: 599.8 of 600.
    return pendulum_swingup(horizon=60, noise=0.3, upright=1.0)


def test_apg_improves_pendulum_balance(tmp_path):
    task = _balance_task()
    policy = GRUPolicy.for_task(task, width=8)
    cfg = optim.APGConfig(iterations=4, steps_per_iteration=50, episodes=8, learning_rate=1e-2, truncation=10)
    key, path = jax.random.PRNGKey(0), tmp_path / "apg.eqx"
    result = optim.train(cfg, task, policy, key, checkpoint=path, progress=False)
    trainer = result.trainer
    before, _ = optim.evaluate(task, *trainer.policy(trainer.init(key)), jax.random.PRNGKey(7), 32)
    after, bal = optim.evaluate(task, *trainer.policy(result.state), jax.random.PRNGKey(7), 32)
    assert float(before.mean()) < 500
    assert float(after.mean()) > 595  # measured 599.9
    assert bool(bal.all())
    assert all(h["nonfinite"] == 0 for h in result.history)
    _, loaded, head = optim.load(path, task, policy)
    assert states_equal(loaded, result.state) and head["iteration"] == 4
    with pytest.raises(ValueError, match="APG has one policy"):
        trainer.policy(result.state, "mean")


def test_an_iteration_continues_adam(short_run):
    """Iteration ``i`` is ``steps_per_iteration`` steps of ``apg_steps`` from ``fold_in(key, i)`` that continue from
    the previous iteration's Adam state, from ``policy.reinit(fold_in(key, 0x5EED))``: the parameters of the
    2-iteration run are those of two such calls by hand."""
    result, _, task, policy, _ = short_run("APGConfig")
    cfg, trainer = result.trainer.config, result.trainer
    params, unravel = optim.flatten_policy(policy.reinit(jax.random.fold_in(RUN_KEY, 0x5EED)))
    init = trainer.init(RUN_KEY)
    np.testing.assert_array_equal(init.params, params)  # the policy's architecture, weights drawn from the key
    norm, opt = init.normalizer, init.opt_state
    steps = jax.jit(lambda p, n, o, k: optim.apg_steps(task, unravel, p, n, k, steps=cfg.steps_per_iteration,
                                                       episodes=cfg.episodes, learning_rate=cfg.learning_rate,
                                                       opt_state=o))
    for i in range(2):
        res = steps(params, norm, opt, jax.random.fold_in(RUN_KEY, i))
        params, norm, opt = res.params, res.normalizer, res.opt_state
        np.testing.assert_allclose(result.history[i]["best_return"], np.max(res.returns), rtol=1e-12)
    # the same program inside another jit: float64 round-off only
    np.testing.assert_allclose(result.state.params, params, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(result.state.normalizer.mean, norm.mean, rtol=1e-10, atol=1e-13)
    assert int(opt.count) == int(result.state.opt_state.count) == 2 * cfg.steps_per_iteration  # Adam's step count
