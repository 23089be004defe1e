"""The one host loop (optim/train.py, ``optim.train``): every algorithm (CE-APG, CEM, PAPG, APG, SHAC) runs through it
and ends at the state of its own init-and-update loop, bit for bit, with one history entry per iteration (cumulative
env steps), deterministic evaluations before training, every ``eval_every`` iterations and after the last (on the
same starts), and a checkpoint that ``optim.load`` turns back into the same state; a run interrupted after an
iteration and resumed from its checkpoint continues exactly (CE-APG and SHAC); a resume may grow the iteration
count (the new config's schedule applies from there) but not shrink it below what is done. (What a resume refuses:
test_checkpoint.py.)"""

import dataclasses
import json
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import optim
from optim import checkpoint
from optim.train import describe
from policies import MLPPolicy
from tests.helpers import (ALGORITHMS, EVAL_KEY, EVALUATED, RUN_KEY, RUN_SEED, reuse_trainers, small_problem,
                           states_equal, tiny_acrobot, tiny_gru, tiny_mlp)


def _without_elapsed(history):
    return [{k: v for k, v in h.items() if k != "elapsed"} for h in history]


@pytest.mark.parametrize("name", ALGORITHMS)
def test_every_algorithm_trains_through_train(name, short_run):
    result, path, task, policy, steps = short_run(name)
    cfg, trainer = result.trainer.config, result.trainer
    assert type(cfg).__name__ == name and cfg == small_problem(name)[0] and trainer.task is task
    init = trainer.init(RUN_KEY)
    manual = init
    for _ in range(2):
        manual, _ = trainer.update(manual)
    assert states_equal(result.state, manual) and int(result.state.iteration) == 2
    assert not states_equal(result.state._replace(iteration=init.iteration), init)  # it trained
    assert [h["iteration"] for h in result.history] == [1, 2]
    assert [h["env_steps"] for h in result.history] == [steps, 2 * steps]
    assert 0 < result.history[0]["elapsed"] <= result.history[1]["elapsed"]
    assert all(h["nonfinite"] == 0 for h in result.history)
    if name in EVALUATED:
        assert [c["iteration"] for c in result.curve] == [0, 1, 2]
        assert [c["env_steps"] for c in result.curve] == [0.0, steps, 2 * steps]
        evaluate = jax.jit(lambda s: optim.evaluate(task, *trainer.policy(s), EVAL_KEY, 3))
        for state, point in ((trainer.init(RUN_KEY), result.curve[0]), (result.state, result.curve[-1])):
            rets, bal = evaluate(state)
            np.testing.assert_allclose(point["return"], float(np.mean(rets)), rtol=1e-12)
            np.testing.assert_allclose(point["return_std"], float(np.std(rets)), rtol=1e-12, atol=1e-12)
            assert point["balanced"] == float(np.mean(bal))
        assert result.curve[0]["return"] != result.curve[-1]["return"]
    else:
        assert result.curve == []
    # the checkpoint: optim.load rebuilds the trainer from the header and gives the same state back
    loaded_trainer, loaded, head = optim.load(path, task, policy)
    assert loaded_trainer.config == cfg and states_equal(loaded, result.state)
    assert head["iteration"] == 2 and head["seed"] == RUN_SEED and head["identity"] == describe(task, policy)
    np.testing.assert_equal(head["history"], result.history)  # NaN where SHAC finished no episode
    assert head["curve"] == result.curve


def test_describe_names_the_task_and_the_policy():
    """The task's and policy's classes and sizes, and every field of the task and its chain, by name: a number as it
    is, an array as its dtype, shape and values (a digest beyond 16 entries), a solver as its class and fields."""
    task = tiny_acrobot(trig=True)
    identity = describe(task, tiny_gru(task, width=8))
    assert {k: v for k, v in identity.items() if not k.startswith("task.")} == {
        "task": "Acrobot", "bodies": "rods", "horizon": 20, "observation_size": 6, "action_size": 1,
        "policy": "GRUPolicy", "policy_parameters": optim.flatten_policy(tiny_gru(task, width=8))[0].size}
    assert identity["task.chain"] == "Chain"
    assert identity["task.chain.bodies[0].mass"] == identity["task.chain.bodies[1].mass"] == "float64[] [2.5]"
    assert len([k for k in identity if k.startswith("task.chain.bodies[") and k.endswith("].mass")]) == 2
    assert identity["task.chain.motors[0].gear"] == "float64[] [25.0]" and "task.chain.motors[1]" not in identity
    assert identity["task.chain.bodies[1].joints[0]"] == "Hinge"  # the second link's joint is revolute
    assert (identity["task.dt"], identity["task.noise"], identity["task.substeps"]) == (0.01, 0.01, 1)
    assert identity["task.solver"] == "RK4" and identity["task.trig"] is True and identity["task.starts"] is None
    starts = np.linspace(0.0, 1.0, 40).reshape(10, 4)
    with_starts = describe(tiny_acrobot(starts=starts), tiny_gru(task))["task.starts"]
    assert with_starts.startswith("float64[10, 4] sha256 ") and len(with_starts.split()[-1]) == 16
    assert json.loads(json.dumps(identity)) == identity  # what a checkpoint header holds, unchanged


def _interrupt_after(monkeypatch, iteration):
    """Make the next ``optim.train`` stop (KeyboardInterrupt) right after it has checkpointed ``iteration``."""
    save = checkpoint.save

    def save_then_stop(path, state, **header):
        save(path, state, **header)
        if header["iteration"] == iteration:
            raise KeyboardInterrupt

    monkeypatch.setattr(checkpoint, "save", save_then_stop)


@pytest.mark.parametrize("name", ["CEAPGConfig", "SHACConfig"])
def test_interrupted_and_resumed_runs(name, short_run, tmp_path, monkeypatch):
    """The run of 2 iterations (``iterations=2``) is resumed with ``iterations=4``, interrupted right after it has
    checkpointed iteration 3, and resumed again. The result is, bit for bit, two updates of the 2-iteration trainer
    and two of the 4-iteration one (a grown run follows the new config's schedule from where it resumes); the history
    keeps every iteration. SHAC's learning rates are constant here, so it is also the uninterrupted 4-iteration run;
    CE-APG's log-linear schedule over 2 iterations differs from the one over 4, and so does its run. (The resume gets
    the trainer the interrupted run built for the same config, task and policy, ``tests.helpers.reuse_trainers``,
    instead of compiling its update again.)"""
    reuse_trainers(monkeypatch)
    first, short_path, task, policy, steps = short_run(name)
    longer = dataclasses.replace(first.trainer.config, iterations=4)
    path = tmp_path / "run.eqx"
    path.write_bytes(short_path.read_bytes())
    with monkeypatch.context() as m:
        _interrupt_after(m, 3)
        with pytest.raises(KeyboardInterrupt):
            optim.train(longer, task, policy, RUN_KEY, checkpoint=path, resume=True, seed=RUN_SEED, progress=False)
    head = checkpoint.read_header(path)
    assert head["iteration"] == 3 and head["config"]["iterations"] == 4 and len(head["history"]) == 3
    resumed = optim.train(longer, task, policy, RUN_KEY, checkpoint=path, resume=True, seed=RUN_SEED, progress=False)
    state, history = first.trainer.init(RUN_KEY), []
    for trainer in (first.trainer, first.trainer, resumed.trainer, resumed.trainer):
        state, metrics = trainer.update(state)
        history.append({k: np.flatnonzero(v).tolist() if np.ndim(v) else float(v) for k, v in metrics.items()
                        if k != "env_steps"})
    assert int(resumed.state.iteration) == 4 and states_equal(resumed.state, state)
    assert [h["env_steps"] for h in resumed.history] == [steps * i for i in (1, 2, 3, 4)]
    np.testing.assert_equal([{k: h[k] for k in history[0]} for h in resumed.history], history)
    np.testing.assert_equal(_without_elapsed(resumed.history[:2]), _without_elapsed(first.history))
    assert resumed.curve == first.curve  # no evaluations asked for: the first run's kept
    uninterrupted = resumed.trainer.init(RUN_KEY)
    for _ in range(4):
        uninterrupted, _ = resumed.trainer.update(uninterrupted)
    assert states_equal(resumed.state, uninterrupted) == (name == "SHACConfig")
    # ... but a resume cannot shrink the run: a shorter one (e.g. --quick) cannot take a longer one as its own
    with pytest.raises(checkpoint.CheckpointError, match=r"4 iterations done, more than the config's iterations=3"):
        optim.train(dataclasses.replace(longer, iterations=3), task, policy, RUN_KEY, checkpoint=path, resume=True,
                    seed=RUN_SEED, progress=False)


@pytest.mark.parametrize("eval_every", [0, -1, 1.5, True, "2"])
def test_train_refuses_bad_eval_every(eval_every):
    cfg, task, policy, _ = small_problem("APGConfig")
    with pytest.raises(ValueError, match="eval_every must be None or an integer >= 1"):
        optim.train(cfg, task, policy, jax.random.PRNGKey(0), eval_every=eval_every, progress=False)


def test_a_nan_in_the_training_state_stops_the_run_before_it_is_checkpointed(tmp_path):
    """An update that leaves a NaN in the state (a bug, or a task that returns NaN without an error) is never
    written: the run stops naming the leaf, and its checkpoint keeps the iteration before."""

    class State(NamedTuple):
        x: jax.Array
        iteration: jax.Array

    @dataclasses.dataclass(frozen=True)
    class Breaks(optim.AlgorithmConfig):
        iterations: int = 3

        def make_trainer(self, task, policy, *, objective=None):
            def update(state):
                x = jnp.where(state.iteration == 1, jnp.nan, state.x + 1.0)
                return State(x, state.iteration + 1), {"env_steps": 1.0, "nonfinite": 0}

            return optim.Trainer(lambda key: State(jnp.zeros(2), jnp.asarray(0)), jax.jit(update),
                                 lambda state, which="best": (policy, None), task, self)

    task = tiny_acrobot()
    path = tmp_path / "run.eqx"
    with pytest.raises(FloatingPointError, match=r"iteration 2 left a NaN in the training state \(\.x\); .*"
                                                 r"run\.eqx keeps iteration 1"):
        optim.train(Breaks(), task, tiny_mlp(task), RUN_KEY, checkpoint=path, progress=False)
    assert checkpoint.read_header(path)["iteration"] == 1


def test_train_refuses_what_does_not_fit_before_any_work(short_run, monkeypatch):
    """A key that is not one PRNG key, no evaluation episodes, and a policy built for another task (another
    observation or action size) are refused by name before anything is compiled or written. (The runs that are not
    refused train the ``short_run`` fixture's APG problem with its trainer, ``tests.helpers.reuse_trainers``: compiled
    once for the tests of optim.)"""
    result, _, task, policy, _ = short_run("APGConfig")
    cfg = result.trainer.config
    reuse_trainers(monkeypatch, (result.trainer, policy))
    cases = [
        (dict(key=0), r"train: key must be one PRNG key \(jax\.random\.PRNGKey\(seed\) or jax\.random\.key"),
        (dict(key=jax.random.split(RUN_KEY, 2)), r"train: key must be one PRNG key"),
        (dict(eval_every=1, eval_episodes=0), r"train: eval_episodes must be an integer >= 1, got 0"),
        (dict(policy=tiny_mlp(tiny_acrobot())), r"the policy \(MLPPolicy\) does not take the task's observation of "
                                                r"shape \(2,\): .*Build it for the task: MLPPolicy\.for_task\(task"),
        (dict(policy=MLPPolicy(2, 3, 4, 1, key=RUN_KEY)), r"returns actions of shape \(3,\), the task takes \(1,\)"),
    ]
    for change, message in cases:
        args = {"key": RUN_KEY, "policy": policy, **change}
        with pytest.raises(ValueError, match=message):
            optim.train(cfg, task, args.pop("policy"), args.pop("key"), progress=False, **args)
    typed = optim.train(cfg, task, policy, jax.random.key(7), progress=False).state  # one key too, stored as raw
    assert states_equal(typed, optim.train(cfg, task, policy, jax.random.PRNGKey(7), progress=False).state)
