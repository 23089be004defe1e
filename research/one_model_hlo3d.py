"""Did the one model (issue 63) change the 3-D programs? The old head and the new one, compiled side by side.

Question: the ant and the humanoid (DFlex's, ``Ant.diffrl()``, ``Humanoid.diffrl()``) go through the general
rigid-body algorithms before and after; do their batched rollouts (batch 16, 3 control steps of the task's solver and
substeps) and gradients (reverse mode, with respect to the controls) compile to the same optimised HLO? The text is
compared stripped of its source locations (metadata, stack frame ids, file names), in float64.

    python -m research.one_model_hlo3d --old /path/to/old/checkout --new /path/to/new/checkout

Writes ``research/results/one_model_hlo3d.json``: each program's SHA-256 per checkout. Each checkout's programs are
compiled by this module with ``--child`` in a fresh interpreter importing that checkout.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import re
import subprocess
import sys


def _strip(hlo: str) -> str:
    hlo = hlo.split("\nFileNames")[0]
    hlo = re.sub(r",? ?metadata=\{[^}]*\}", "", hlo)
    return re.sub(r",? ?stack_frame_id=\d+", "", hlo)


def child() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import lagrange as lg
    from lagrange.tasks import Ant, Humanoid

    out = {}
    for name, task in (("ant", Ant.diffrl()), ("humanoid", Humanoid.diffrl())):
        tree, batch = task.chain, 16
        q = jnp.broadcast_to(jnp.asarray(task.start), (batch, tree.nq))
        qd, u = jnp.zeros((batch, tree.nv)), jnp.zeros((batch, 3, tree.m))
        opts = lg.compiler_options(tree)

        def final(q, qd, u, tree=tree, task=task):
            return lg.simulate(tree, q, qd, u, task.dt, task.solver, 2, check=False).q[-1]

        fwd = jax.jit(jax.vmap(final), compiler_options=opts)
        grad = jax.jit(jax.vmap(jax.grad(lambda *x: jnp.sum(final(*x)), argnums=2)), compiler_options=opts)
        for kind, f in (("forward", fwd), ("gradient", grad)):
            text = _strip(f.lower(q, qd, u).compile().as_text())
            out[f"{name} {kind}"] = hashlib.sha256(text.encode()).hexdigest()
    print(json.dumps(out))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child()
    res = {}
    for label, root in (("old", args.old), ("new", args.new)):
        env = dict(os.environ, PYTHONPATH=str(pathlib.Path(root).resolve()))
        proc = subprocess.run([sys.executable, __file__, "--old", "-", "--new", "-", "--child"], env=env, check=True,
                              capture_output=True, text=True, cwd=root)
        res[label] = json.loads(proc.stdout.strip().splitlines()[-1])
    res["identical"] = {k: res["old"][k] == res["new"][k] for k in res["old"]}
    path = pathlib.Path(__file__).parent / "results" / "one_model_hlo3d.json"
    path.write_text(json.dumps(res, indent=1) + "\n")
    print(json.dumps(res["identical"]))


if __name__ == "__main__":
    main()
