"""Fixtures of the tests of optim: ``short_run``, one small run of each algorithm through ``optim.train`` made once per
session and shared by the host-loop, checkpoint, APG, PAPG, SHAC and ``scan_train`` tests (each run is a
compilation); ``sharded_runs``, some of those runs in a fresh interpreter with 2 host devices, started as the
session starts when test_devices.py's comparison is to run, so that it computes beside the other tests."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

import optim
from tests.helpers import EVAL_KEY, EVALUATED, ROOT, RUN_KEY, RUN_SEED, small_problem


@pytest.fixture(scope="session")
def short_run(tmp_path_factory):
    """``short_run(name) -> (result, checkpoint path, task, policy, env steps per iteration)``: the 2-iteration run
    of ``tests.helpers.small_problem(name)`` by ``optim.train`` from ``PRNGKey(7)`` with seed 7 and a checkpoint
    (``resume=True`` without a checkpoint there: a fresh run), with deterministic evaluations on 3 starts from
    ``PRNGKey(5)`` after every iteration for CE-APG and SHAC (``tests.helpers.RUN_KEY``, ``RUN_SEED``, ``EVAL_KEY``,
    ``EVALUATED``). Read the checkpoint; never write it."""
    runs = {}

    def run(name):
        if name not in runs:
            cfg, task, policy, steps = small_problem(name)
            path = tmp_path_factory.mktemp(name) / "run.eqx"
            result = optim.train(cfg, task, policy, RUN_KEY, checkpoint=path, resume=True, seed=RUN_SEED,
                                 progress=False, eval_every=1 if name in EVALUATED else None, eval_episodes=3,
                                 eval_key=EVAL_KEY)
            runs[name] = result, path, task, policy, steps
        return runs[name]

    return run


_SHARDED_RUNS = textwrap.dedent(
    """
    import json, jax
    jax.config.update("jax_enable_x64", True)
    import optim
    from tests.helpers import RUN_KEY, SHARDED, small_problem

    out = {"devices": len(jax.devices())}
    for name in SHARDED:
        cfg, task, policy, _ = small_problem(name)
        state = optim.train(cfg, task, policy, RUN_KEY, progress=False).state
        out[name] = [leaf.tolist() for leaf in jax.tree_util.tree_leaves(state)]
    print(json.dumps(out))
    """
)


@pytest.fixture(scope="session")
def sharded_runs():
    """``sharded_runs(devices) -> {"devices": n, name: [leaves of the final state], ...}``: the ``short_run`` runs
    of ``tests.helpers.SHARDED`` in a fresh interpreter with ``devices`` forced CPU devices (float64). The 2-device
    interpreter starts with the fixture; any other is started when asked for."""
    procs = {}

    def start(devices):
        env = dict(os.environ, JAX_PLATFORMS="cpu",
                   XLA_FLAGS=f"{os.environ['XLA_FLAGS']} --xla_force_host_platform_device_count={devices}")
        procs[devices] = subprocess.Popen([sys.executable, "-c", _SHARDED_RUNS], stdout=subprocess.PIPE,
                                          stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)

    def result(devices):
        if devices not in procs:
            start(devices)
        out, err = procs[devices].communicate(timeout=600)
        assert procs[devices].returncode == 0, err[-3000:]
        return json.loads(out.strip().splitlines()[-1])

    start(2)
    yield result
    for proc in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="session", autouse=True)
def _start_the_sharded_runs_early(request):
    """Start ``sharded_runs`` with the session when test_devices.py's comparison is among the tests to run."""
    wanted = "test_devices.py::test_sharded_equals_single_device"
    if any(item.nodeid.endswith(wanted) for item in request.session.items):
        request.getfixturevalue("sharded_runs")
