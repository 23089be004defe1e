"""Devices (optim/devices.py): CE-APG's candidates (5, padded to 6), PAPG's runs and SHAC's environments sharded over
2 forced host devices give the single-device states after 2 iterations of ``optim.train``; ``use_cpu_cores`` splits
the host into one device per core before JAX starts (and only then), refusing bad counts."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

from tests.helpers import ROOT, SHARDED

def test_sharded_equals_single_device(sharded_runs, short_run):
    """The ``short_run`` fixture's 2-iteration CE-APG (5 candidates, padded to 6), PAPG (2 runs) and SHAC (4
    environments) runs, in a fresh interpreter with 2 forced host devices (``sharded_runs``, started with the session),
    against the same runs on this process's single device. The same computation per candidate, run or environment;
    what crosses devices (SHAC's sums over environments, the elite refit) is only reassociated, so the states agree
    to float64 round-off: 1e-12 relative (4500 eps) plus 1e-14 absolute (45 eps); measured at most 2.2e-14 relative
    and 3.3e-16 absolute (not bit for bit: 2 of CE-APG's 64 entries, 2 of PAPG's 49 and 161 of SHAC's 372 differ in
    the last bits)."""
    if len(jax.devices()) == 1:
        one = {"devices": 1} | {name: [np.asarray(leaf).tolist() for leaf in jax.tree_util.tree_leaves(
            short_run(name)[0].state)] for name in SHARDED}
    else:  # this process was given several devices: the single-device runs in a fresh interpreter too
        one = sharded_runs(devices=1)
    two = sharded_runs(devices=2)
    assert (two["devices"], one["devices"]) == (2, 1)
    for name in SHARDED:
        assert len(two[name]) == len(one[name])
        for a, b in zip(two[name], one[name]):
            np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-12, atol=1e-14,
                                       err_msg=name)


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


def test_population_mesh_and_shard_count():
    """In this process (one CPU device unless XLA_FLAGS forces more) a population is never split over more devices
    than it has members, and ``divides`` keeps the count a divisor of the size."""
    import jax

    from optim.devices import population_mesh, shard_count

    n = len(jax.devices())
    assert shard_count(1) == 1 and shard_count(10**6) == n
    assert 7 % shard_count(7, divides=True) == 0 and shard_count(7, divides=True) <= min(7, n)
    mesh = population_mesh(3)
    assert mesh.axis_names == ("population",) and len(mesh.devices) == min(3, n)
