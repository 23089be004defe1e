"""Did the one model (issue 63) change the planar programs' speed? The old head and the new one, side by side.

Question: with every planar model a ``Tree`` lowered to the planar backend while tracing, do the rollouts of the
published throughput rows run as fast as before? The compiled programs are compared too: the optimised HLO of each
batched rollout and gradient, stripped of its source locations, old against new.

Method: the lagrange rows of ``python -m benchmarks.throughput`` (the acrobot at batch 1024, semi-implicit Euler and
RK4; n-link pendulums of 4, 8, 16 and 32 links, semi-implicit Euler; Gymnasium's half-cheetah in free flight and
DFlex's hopper on the ground at batch 1024), forward (final state) and gradient (reverse mode, with respect to the
controls), each timed in a fresh interpreter per checkout and round: rounds alternate old, new, old, new, ... so both
see the same machine, and the run-to-run noise is the spread between the old head's rounds.

    python -m research.one_model_speed --old /path/to/old/checkout --new /path/to/new/checkout [--rounds 3]

Writes ``research/results/one_model_speed.json``. Each round's child is this module with ``--child``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import time

ROWS = ["acrobot sie", "acrobot rk4", "pendulum4", "pendulum8", "pendulum16", "pendulum32", "half_cheetah", "hopper"]
B, T = 1024, 20


def _models():
    import gymnasium

    import lagrange as lg
    from lagrange.interop.mjcf import from_mjcf
    from lagrange.tasks.locomotion import hopper_chain

    assets = pathlib.Path(gymnasium.__file__).parent / "envs/mujoco/assets"
    sie, rk4 = lg.SemiImplicitEuler(), lg.RK4()
    acrobot = lg.systems.acrobot()
    out = {"acrobot sie": (acrobot, sie, 0.01, 1), "acrobot rk4": (acrobot, rk4, 0.01, 1)}
    for n in (4, 8, 16, 32):
        out[f"pendulum{n}"] = (lg.systems.n_link_pendulum(n, gear=1.0), sie, 0.01, 1)
    out["half_cheetah"] = (from_mjcf(assets / "half_cheetah.xml", limits="ignore", contact="ignore"), sie, 0.01, 5)
    out["hopper"] = (hopper_chain(), lg.SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True), 1 / 60, 16)
    return out


def _strip(hlo: str) -> str:
    hlo = hlo.split("\nFileNames")[0]
    hlo = re.sub(r",? ?metadata=\{[^}]*\}", "", hlo)
    return re.sub(r",? ?stack_frame_id=\d+", "", hlo)


def child(out_path: str) -> None:
    """Time every row once in this interpreter and write ``{row: {forward, gradient, hlo}}``."""
    import hashlib

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import lagrange as lg

    result = {}
    rng = np.random.default_rng(0)
    for name, (chain, solver, dt, substeps) in _models().items():
        n, m = (chain.nv if hasattr(chain, "nv") else chain.n), chain.m  # the old head's chains had n only
        q0 = jnp.asarray(rng.uniform(-0.1, 0.1, (B, n)))
        qd0 = jnp.zeros((B, n))
        us = jnp.asarray(rng.uniform(-0.5, 0.5, (B, T, m)))

        def final(q, qd, u):
            tr = lg.simulate(chain, q, qd, u, dt, solver, substeps, check=False)
            return tr.q[-1], tr.qd[-1]

        def loss(q, qd, u):
            qT, qdT = final(q, qd, u)
            return jnp.sum(qT**2) + jnp.sum(qdT**2)

        row = {}
        for kind, fn in (("forward", jax.jit(jax.vmap(final))), ("gradient", jax.jit(jax.vmap(jax.grad(loss, 2))))):
            lowered = fn.lower(q0, qd0, us).compile()
            row[f"{kind}_hlo"] = hashlib.sha256(_strip(lowered.as_text()).encode()).hexdigest()[:16]
            jax.block_until_ready(fn(q0, qd0, us))
            best = np.inf
            for _ in range(5):
                t = time.perf_counter()
                jax.block_until_ready(fn(q0, qd0, us))
                best = min(best, time.perf_counter() - t)
            row[kind] = B * T / best  # env-steps per second
        result[name] = row
    pathlib.Path(out_path).write_text(json.dumps(result))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=False)
    ap.add_argument("--new", required=False)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child(args.child)
    here = pathlib.Path(__file__).resolve()
    runs: dict[str, list[dict]] = {"old": [], "new": []}
    for r in range(args.rounds):
        for which, root in (("old", args.old), ("new", args.new)):
            out = pathlib.Path(f"/tmp/one_model_speed_{which}_{r}.json")
            env = dict(os.environ, PYTHONPATH=str(pathlib.Path(root).resolve()))
            subprocess.run([sys.executable, str(here), "--child", str(out)], check=True, env=env,
                           cwd=str(pathlib.Path(root).resolve()), stderr=subprocess.DEVNULL)
            runs[which].append(json.loads(out.read_text()))
            print(f"round {r} {which} done", flush=True)
    summary = {}
    for name in ROWS:
        summary[name] = {}
        for kind in ("forward", "gradient"):
            old = [run[name][kind] for run in runs["old"]]
            new = [run[name][kind] for run in runs["new"]]
            summary[name][kind] = dict(
                old=old, new=new, new_over_old=float(max(new) / max(old)),
                old_spread=float(max(old) / min(old)), new_spread=float(max(new) / min(new)),
                same_program=all(run[name][f"{kind}_hlo"] == runs["old"][0][name][f"{kind}_hlo"]
                                 for run in runs["old"] + runs["new"]))
    path = here.parent / "results" / "one_model_speed.json"
    path.write_text(json.dumps(dict(batch=B, steps=T, rounds=args.rounds, rows=summary), indent=1))
    for name, kinds in summary.items():
        for kind, s in kinds.items():
            print(f"{name:14s} {kind:8s} best new/old {s['new_over_old']:.3f}  spread old {s['old_spread']:.3f} "
                  f"new {s['new_spread']:.3f}  same program {s['same_program']}")


if __name__ == "__main__":
    main()
