"""Devices (optim/devices.py): candidates sharded over 4 forced host devices give the single-device result, and
``use_cpu_cores`` splits the host into one device per core before JAX starts (and only then), refusing bad counts."""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from tests.helpers import ROOT


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
