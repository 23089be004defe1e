"""Rows of ``benchmarks/derivation_overhead.py`` for an older revision and this checkout, measured alternately.

    python -m research.derivation_ab --old 952bce9     # the code before the sign folding and literals
    python -m research.derivation_ab --old 952bce9 --rows double_cartpole,1,forward --rounds 3
    python -m research.derivation_ab --old 952bce9 --training acrobot,cartpole   # s per CE iteration

On a shared machine the absolute times of one run drift by tens of percent, so a change is judged by the ratio
lagrange / closed form measured in the same process, for the old and the new code in turn: each round runs one
process on a ``git worktree`` of ``--old`` and one on this checkout, and prints every row's ratio. With
``--training TASKS`` it times instead the CE-APG iterations of ``CEAPGConfig.laptop(task)`` (the examples' default),
one JAX CPU device per core: the median seconds of ``--repeats`` iterations after the first (compiling) one (the
trainer built with the API of each revision, :func:`laptop_trainer`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROWS = "double_cartpole,1024,gradient;acrobot,1024,gradient;double_cartpole,1,forward"


def measure(rows: str, repeats: int) -> list[dict]:
    """The rows ``name,batch,mode;...`` with the ``lagrange`` and ``closed form`` variants of whatever
    ``benchmarks.derivation_overhead`` is first on ``sys.path``."""
    import jax.numpy as jnp
    import numpy as np

    import lagrange
    from benchmarks import derivation_overhead as do

    assert lagrange.__file__.startswith(sys.path[0]), (lagrange.__file__, sys.path[0])  # the tree asked for
    out = []
    for spec in rows.split(";"):
        name, batch, mode = spec.split(",")
        batch = int(batch)
        make_chain, closed, q_init = do.SYSTEMS[name]
        variants = do._variants(make_chain(), closed)
        fns = {v: do._build(variants[v], mode) for v in ("lagrange", "closed form")}
        # derivation_overhead.inputs, written out: the old revision's module may predate it
        n = len(q_init)
        rng = np.random.default_rng(0)
        q0 = jnp.asarray(np.asarray(q_init)[None] + 0.01 * rng.standard_normal((batch, n)), jnp.float32)
        qd0 = jnp.zeros((batch, n), jnp.float32)
        us = jnp.asarray(0.3 * rng.standard_normal((do.STEPS, batch, 1)), jnp.float32)
        args = (q0, qd0, us)
        for f in fns.values():
            do._time(f, args)
        calls = {v: max(1, int(0.02 / max(do._time(f, args), 1e-6))) for v, f in fns.items()}
        times = {v: [] for v in fns}
        for _ in range(repeats):
            for v, f in fns.items():
                times[v].append(do._time(f, args, calls[v]))
        med = {v: float(np.median(t)) for v, t in times.items()}
        out.append({"row": spec, "lagrange_ms": 1e3 * med["lagrange"], "closed_ms": 1e3 * med["closed form"],
                    "ratio": med["lagrange"] / med["closed form"]})
    return out


def laptop_trainer(task: str, **overrides):
    """The CE-APG trainer of ``CEAPGConfig.laptop(task)`` (with ``overrides``) in whichever revision is imported: since
    issue 30 the config holds settings only and the task and policy are passed (those the laptop protocol trained
    before: the rods, the acrobot observing (sin, cos), the paper's GRU width); before it, the config named them."""
    import optim

    if hasattr(optim, "train"):  # the API since issue 30
        from lagrange.tasks import PAPER_TASKS
        from policies import GRUPolicy

        env = PAPER_TASKS[task].rods(**({"trig": True} if task == "acrobot" else {}))
        policy = GRUPolicy.for_task(env, 32 if task == "double_cartpole" else 16)
        return optim.CEAPGConfig.laptop(task, **overrides).make_trainer(env, policy)
    from optim import ce_apg

    return ce_apg.make_trainer(ce_apg.CEAPGConfig.laptop(task, **overrides))


def measure_training(tasks: str, repeats: int) -> list[dict]:
    """Seconds per CE-APG iteration of the laptop preset, for each task in ``tasks`` (comma-separated)."""
    import time

    import jax
    import numpy as np

    import lagrange
    from optim.devices import cpu_core_count, use_cpu_cores

    assert lagrange.__file__.startswith(sys.path[0]), (lagrange.__file__, sys.path[0])
    use_cpu_cores(cpu_core_count())
    out = []
    for task in tasks.split(","):
        trainer = laptop_trainer(task)
        state = trainer.init(jax.random.PRNGKey(0))
        state, _ = trainer.update(state)  # compiles
        jax.block_until_ready(state)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            state, _ = trainer.update(state)
            jax.block_until_ready(state)
            times.append(time.perf_counter() - t0)
        out.append({"row": f"{task} CE-APG iteration", "seconds": float(np.median(times))})
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old", required=True, help="git revision to compare against")
    p.add_argument("--rows", default=ROWS, help="name,batch,mode;... (default: %(default)s)")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--training", metavar="TASKS", help="time CE-APG iterations of these tasks instead (a,b,...)")
    p.add_argument("--child", help=argparse.SUPPRESS)  # the tree to import from, in a worker process
    args = p.parse_args(argv)
    if args.child:
        sys.path.insert(0, args.child)
        rows = measure_training(args.training, args.repeats) if args.training else measure(args.rows, args.repeats)
        print(json.dumps(rows))
        return
    with tempfile.TemporaryDirectory() as tmp:
        old = os.path.join(tmp, "old")
        subprocess.run(["git", "-C", HERE, "worktree", "add", "--detach", "-q", old, args.old], check=True)
        try:
            for r in range(args.rounds):
                for label, tree in (("old " + args.old, old), ("this checkout", HERE)):
                    extra = ["--training", args.training] if args.training else []
                    res = subprocess.run([sys.executable, os.path.abspath(__file__), "--old", args.old, "--rows",
                                          args.rows, "--repeats", str(args.repeats), "--child", tree, *extra],
                                         capture_output=True, text=True, check=True, cwd=tree)
                    for row in json.loads(res.stdout.strip().splitlines()[-1]):
                        if "seconds" in row:
                            print(f"round {r + 1} {label:18s} {row['row']:28s} {row['seconds']:.3f} s", flush=True)
                            continue
                        print(f"round {r + 1} {label:18s} {row['row']:28s} lagrange {row['lagrange_ms']:9.3f} ms  "
                              f"closed form {row['closed_ms']:9.3f} ms  ratio {row['ratio']:.3f}", flush=True)
        finally:
            subprocess.run(["git", "-C", HERE, "worktree", "remove", "--force", old], check=False)


if __name__ == "__main__":
    main()
