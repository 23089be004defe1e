"""Which of the library's files does one call of ``lg.simulate`` pass through (issue 63)?

Question: how many of ``lagrange/``'s files does a planar chain's ``simulate`` enter, and how often does it check the
tree? Issue 63 asks for at most 8 files with the checks run once.

Method: ``sys.setprofile`` records every Python call made in a file under ``lagrange/`` during one un-jitted
``lg.simulate`` (the trace a ``jax.jit`` of it runs once): the acrobot (unrolled derivation), a 5-link pendulum
(recursive algorithms) and Gymnasium's ant read from MJCF (general algorithms), each traced twice: cold (its first
call: the tree checked, lowered and prepared) and warm (the dispatch finds it prepared). Also counted: the calls of
``check_tree`` and ``check_parameters``.

    python -m research.call_path

Writes ``research/results/call_path.json``.
"""

from __future__ import annotations

import collections
import json
import os
import pathlib
import sys

import jax
import jax.numpy as jnp

import lagrange as lg
from lagrange.tasks import Ant

ROOT = os.path.dirname(lg.__file__)


def trace(tree, q0, qd0, us):
    files, calls = collections.Counter(), collections.Counter()

    def profile(frame, event, arg):
        if event == "call" and frame.f_code.co_filename.startswith(ROOT):
            files[os.path.relpath(frame.f_code.co_filename, ROOT)] += 1
            calls[frame.f_code.co_name] += 1

    sys.setprofile(profile)
    try:
        lg.simulate(tree, q0, qd0, us, 0.01)
    finally:
        sys.setprofile(None)
    return {"files": dict(files.most_common()), "n_files": len(files),
            "check_tree": calls["check_tree"], "check_parameters": calls["check_parameters"]}


def main():
    jax.config.update("jax_enable_x64", True)
    models = {"acrobot": lg.systems.acrobot(), "pendulum5": lg.systems.n_link_pendulum(5), "ant": Ant.diffrl().chain}
    out = {}
    for name, tree in models.items():
        q0, qd0, us = jnp.zeros(tree.nq), jnp.zeros(tree.nv), jnp.zeros((3, tree.m))
        if name == "ant":
            q0 = q0.at[3].set(1.0)  # the free joint's unit quaternion
        out[name] = {"cold": trace(tree, q0, qd0, us), "warm": trace(tree, q0, qd0, us)}
        for when in ("cold", "warm"):
            r = out[name][when]
            print(f"{name:10s} {when}: {r['n_files']:2d} files, check_tree {r['check_tree']}, check_parameters "
                  f"{r['check_parameters']}: {', '.join(r['files'])}")
    path = pathlib.Path(__file__).parent / "results" / "call_path.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print("wrote", path)


if __name__ == "__main__":
    main()
