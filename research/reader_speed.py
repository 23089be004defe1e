"""Is a planar MJCF model read body for body (the tree reader) as exact and as fast as the chain reader's links?

Run at commit 32092b5, the last one with both readers (``from_mjcf(..., tree=None)`` the chain reader,
``tree=True`` the tree reader)::

    git worktree add /tmp/reader 32092b5 && cd /tmp/reader && python /work/main/research/reader_speed.py OUT.json

For the nine planar models of ``benchmarks.mjcf_import`` and Gymnasium's hopper (penalty contact and limits),
half-cheetah and walker2d: the largest relative difference of M, the bias forces and q'' at 16 random
states; the StableHLO line count of a jitted, vmapped 20-step semi-implicit Euler rollout (B = 256); and its best of
5 alternating timings, µs per env-step.
"""

import json
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import asset, gymnasium_model  # noqa: E402
from benchmarks.mjcf_import import MODELS  # noqa: E402
from lagrange.interop.mjcf import from_mjcf  # noqa: E402

CASES = {n: (asset(*p), "ignore", "ignore") for n, p in MODELS.items()}
CASES["Gymnasium hopper, contact"] = (gymnasium_model("hopper"), lg.PenaltyLimits(1e3, 10.0),
                                      lg.PenaltyContact(2e4, 1e3, 1e3, 0.9))
CASES["Gymnasium half_cheetah"] = (gymnasium_model("half_cheetah"), "ignore", "ignore")
CASES["Gymnasium walker2d, contact"] = (gymnasium_model("walker2d"), lg.PenaltyLimits(1e3, 10.0),
                                        lg.PenaltyContact(2e4, 1e3, 1e3, 0.9))
B, T = 256, 20


def main(out_path):
    rows = {}
    for name, (path, lim, con) in CASES.items():
        c = from_mjcf(path, limits=lim, contact=con)
        t = from_mjcf(path, limits=lim, contact=con, tree=True)
        rng = np.random.default_rng(0)
        q = rng.uniform(-1, 1, (16, c.nq)) + np.asarray(t.neutral())
        qd, u = rng.uniform(-2, 2, (16, c.nv)), rng.uniform(-1, 1, (16, c.m))
        terms = lambda m: jax.jit(jax.vmap(lambda q, qd, u: (  # noqa: E731
            lg.mass_matrix(m, q), lg.bias_forces(m, q, qd), lg.forward_dynamics(m, q, qd, u if m.m else None))))(
            q, qd, u)
        diff = max(float(jnp.max(jnp.abs(x - y)) / max(1.0, float(jnp.max(jnp.abs(y)))))
                   for x, y in zip(jax.tree.leaves(terms(c)), jax.tree.leaves(terms(t))))
        qs = jnp.asarray(np.asarray(t.neutral()) + 0.01 * rng.standard_normal((B, c.nq)))
        qds, us = jnp.zeros((B, c.nv)), jnp.zeros((B, T, c.m))
        runs, lines = {}, {}
        for label, m in (("chain", c), ("tree", t)):
            g = jax.jit(jax.vmap(lambda q, qd, u, m=m: lg.simulate(m, q, qd, u if m.m else None, 0.002,
                                                                  lg.SemiImplicitEuler(), steps=T).q[-1]))
            jax.block_until_ready(g(qs, qds, us))
            runs[label], lines[label] = g, g.lower(qs, qds, us).as_text().count("\n")
        best = {k: float("inf") for k in runs}
        for _ in range(5):
            for k, g in runs.items():
                t0 = time.perf_counter()
                jax.block_until_ready(g(qs, qds, us))
                best[k] = min(best[k], time.perf_counter() - t0)
        rows[name] = dict(planar=bool(t.planar), max_relative_difference=diff, stablehlo_lines=lines,
                          us_per_env_step={k: v / (B * T) * 1e6 for k, v in best.items()})
        print(name, rows[name], flush=True)
    with open(out_path, "w") as f:
        json.dump(dict(batch=B, steps=T, rows=rows), f, indent=2)


if __name__ == "__main__":
    main(sys.argv[1])
