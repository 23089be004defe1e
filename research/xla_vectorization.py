"""What stops XLA's CPU backend from vectorizing a batched RK4 rollout: a ``negate``, and parameters as operands.

    python -m research.xla_vectorization            # the cartpole, batch 1024, about a minute
    python -m research.xla_vectorization --kernels  # also: which compiled kernels LLVM vectorized

The cartpole rollout of ``benchmarks/derivation_overhead.py`` (RK4, 500 steps of 0.01 s, float32, batch 1024,
forward), timed for variants of the hand-written closed form that each change one thing, beside lagrange itself, all
interleaved in one process. Prints the median time and its ratio to the closed form:

- ``closed form``: ``oracles/closed_form.py`` (constants as Python floats, folded into literals while tracing);
- ``closed form, one negate``: its ``-ml g sin`` term written as ``-(ml g sin)``, which XLA keeps as a ``negate``;
- ``closed form, one * -1``: the same sign as a multiplication by -1.0;
- ``closed form, constants as arrays``: its parameters as ``jnp`` arrays closed over by the jitted function, which
  XLA receives as run-time operands of the loop;
- ``lagrange``: ``lagrange.simulate`` on ``lagrange.systems.cartpole()``.

``--kernels`` compiles each variant again in a child process with ``XLA_FLAGS=--xla_dump_to=...`` and counts, over the
fusion kernels of the rollout, those whose optimised LLVM IR has vector (``<N x float>``) values, and those that load
the loop index inside the loop (the ``%.val = load i32`` that the inlined helper functions leave behind).
"""

from __future__ import annotations

import argparse
import glob
import os
import subprocess
import sys
import tempfile
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.derivation_overhead import DT, SYSTEMS, _build, inputs
import lagrange as lg
from oracles import closed_form as cf


def _cartpole(p, q, qd, u, sign):
    """``oracles.closed_form.cartpole_forward_dynamics`` with its gravity term's sign applied by ``sign``."""
    s, c = jnp.sin(q[..., 1]), jnp.cos(q[..., 1])
    ml = p.pole_mass * p.pole_com
    thd = qd[..., 1]
    a, b, d = cf._cartpole_m(p, c)
    r0 = p.gear * u[..., 0] + ml * s * thd * thd - p.damping * qd[..., 0]
    r1 = sign(ml * p.gravity * s)
    return cf._stack(*cf._solve2(a, b, d, r0, r1))


def variants():
    params = cf.cartpole.Params()
    arrays = cf.cartpole.Params(*[jnp.asarray(v, jnp.float32) for v in params])
    chain = lg.systems.cartpole()

    def closed(fd, p):
        return lambda q0, qd0, us: cf.rollout(fd, p, q0, qd0, us, DT)

    def lagrange_roll(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, DT)
        return tr.q, tr.qd

    return {
        "closed form": closed(cf.cartpole.forward_dynamics, params),
        "closed form, one negate": closed(lambda p, q, qd, u: _cartpole(p, q, qd, u, lambda x: -x), params),
        "closed form, one * -1": closed(lambda p, q, qd, u: _cartpole(p, q, qd, u, lambda x: x * -1.0), params),
        "closed form, constants as arrays": closed(cf.cartpole.forward_dynamics, arrays),
        "lagrange": lagrange_roll,
    }


def kernels(name: str, batch: int) -> str:
    """Compile ``name`` in a child process that dumps XLA's output; count its fusion kernels' vectorization."""
    with tempfile.TemporaryDirectory() as dump:
        env = dict(os.environ, XLA_FLAGS=f"--xla_dump_to={dump}")
        subprocess.run([sys.executable, "-m", "research.xla_vectorization", "--compile-only", name,
                        "--batch", str(batch)], env=env, check=True)
        # the rollout is the module with the while loop (the others are eager helper ops)
        rollout = [f for f in glob.glob(os.path.join(dump, "*after_optimizations.txt")) if " while(" in open(f).read()]
        module = os.path.basename(rollout[0]).split(".")[0]
        files = glob.glob(os.path.join(dump, f"{module}.*fusion*ir-with-opt.ll"))
        texts = [open(f).read() for f in files]
        vectorized = sum("x float>" in t for t in texts)
        reloads = sum("%.val = load i32" in t for t in texts)
    return f"{vectorized} of {len(texts)} fusion kernels vectorized, {reloads} reload the loop index"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batch", type=int, default=1024)
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--kernels", action="store_true", help="also report the vectorized kernels of each variant")
    p.add_argument("--compile-only", metavar="VARIANT", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    q0, qd0, us = inputs(SYSTEMS["cartpole"][2], args.batch)
    if args.compile_only:
        jax.block_until_ready(_build(variants()[args.compile_only], "forward")(q0, qd0, us))
        return
    fns = {name: _build(roll, "forward") for name, roll in variants().items()}
    reference = np.asarray(fns["closed form"](q0, qd0, us)[0])
    for name, f in fns.items():
        hlo = f.lower(q0, qd0, us).compile().as_text()
        err = float(np.max(np.abs(np.asarray(f(q0, qd0, us)[0]) - reference)))
        print(f"{name:34s} negate ops in the compiled program: {hlo.count(' negate('):2d}; "
              f"max |q - closed form| {err:.1e}" + (f"; {kernels(name, args.batch)}" if args.kernels else ""),
              flush=True)
    times = {name: [] for name in fns}
    for _ in range(args.repeats):
        for name, f in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(q0, qd0, us))
            times[name].append(time.perf_counter() - t0)
    ref = np.median(times["closed form"])
    for name, t in times.items():
        print(f"{name:34s} {1e3 * np.median(t):8.2f} ms   / closed form {np.median(t) / ref:5.2f}")


if __name__ == "__main__":
    main()
