"""What the autodiff derivation costs: lagrange against hand-written closed-form equations.

    python -m benchmarks.derivation_overhead            # the table (also: python benchmarks/derivation_overhead.py)
    python -m benchmarks.derivation_overhead --quick    # acrobot only, 3 repeats

Acrobot, cartpole and double cartpole; classic RK4, 500 control steps of 0.01 s (one RK4 step each), float32,
controls (500, 1) from a fixed seed. For each system, batch (1 and 1024, via ``vmap``) and mode (forward: the whole
trajectory; gradient: of a loss on the final state with respect to all controls), it times, interleaved in one run:

- ``lagrange``: ``lagrange.simulate(chain, ..., solver=RK4())`` with its defaults (non-finite check on,
  per-interval ``jax.checkpoint`` on),
- ``closed form``: ``oracles/closed_form.py``, hand-written equations and RK4 in ``lax.scan``,
- ``closed form + remat``: the same with ``jax.checkpoint`` around each interval, as a careful person would add once
  they measured it,
- ``naive autodiff``: Hessians of the Lagrangian and ``jnp.linalg.solve`` (``oracles/euler_lagrange.py``) in the
  same RK4 loop, the derivation this library replaces.

Reported: median wall time over interleaved repeats, compile time, and the ratios ``lagrange / closed form`` and
``lagrange / (closed form + remat)``; on a shared machine absolute times drift, the ratios of one run are what to
compare. Writes ``benchmarks/results/derivation_overhead.{json,md}`` (``--quick``: ``runs/benchmarks/``, not
published).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import lagrange as lg  # noqa: E402
from benchmarks._cli import outputs  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402
from oracles import closed_form as cf  # noqa: E402
from oracles import euler_lagrange as el  # noqa: E402

STEPS, DT = 500, 0.01
SYSTEMS = {
    "acrobot": (lg.systems.acrobot, cf.acrobot, [0.3, 0.2]),
    "cartpole": (lg.systems.cartpole, cf.cartpole, [0.1, 0.3]),
    "double_cartpole": (lg.systems.double_cartpole, cf.double_cartpole, [0.1, 0.3, -0.2]),
}


def _variants(chain, closed):
    params = closed.Params()

    def lagrange_roll(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, DT, solver=lg.RK4())
        return tr.q, tr.qd

    def cf_roll(q0, qd0, us):
        return cf.rollout(closed.forward_dynamics, params, q0, qd0, us, DT)

    def cf_remat_roll(q0, qd0, us):
        step = jax.checkpoint(lambda q, qd, u: cf.rk4_step(closed.forward_dynamics, params, q, qd, u, DT))

        def body(c, u):
            out = step(*c, u)
            return out, out

        _, (qs, qds) = jax.lax.scan(body, (q0, qd0), us)
        return jnp.concatenate([q0[None], qs]), jnp.concatenate([qd0[None], qds])

    def naive_roll(q0, qd0, us):
        return cf.rollout(lambda p, q, qd, u: el.forward_dynamics(chain, q, qd, u), None, q0, qd0, us, DT)

    return {"lagrange": lagrange_roll, "closed form": cf_roll, "closed form + remat": cf_remat_roll,
            "naive autodiff": naive_roll}


def _build(roll, mode):
    if mode == "forward":
        f = roll
    else:

        def loss(q0, qd0, us):
            q, qd = roll(q0, qd0, us)
            return jnp.sum(q[-1] ** 2) + jnp.sum(qd[-1] ** 2)

        f = jax.grad(loss, argnums=2)
    return jax.jit(jax.vmap(f, in_axes=(0, 0, 1)))


def _time(f, args, calls: int = 1):
    """Seconds per call, averaged over ``calls`` back-to-back calls."""
    t0 = time.perf_counter()
    for _ in range(calls):
        jax.block_until_ready(f(*args))
    return (time.perf_counter() - t0) / calls


def inputs(q_init, batch: int):
    """The rollouts' inputs: ``(q0, qd0, us)``, float32, ``q0`` within 0.01 of ``q_init``, controls N(0, 0.3^2)."""
    n = len(q_init)
    rng = np.random.default_rng(0)
    q0 = jnp.asarray(np.asarray(q_init)[None] + 0.01 * rng.standard_normal((batch, n)), jnp.float32)
    qd0 = jnp.zeros((batch, n), jnp.float32)
    us = jnp.asarray(0.3 * rng.standard_normal((STEPS, batch, 1)), jnp.float32)
    return q0, qd0, us


def run(repeats: int, batches, systems):
    rows = []
    for name in systems:
        make_chain, closed, q_init = SYSTEMS[name]
        chain = make_chain()
        variants = _variants(chain, closed)
        for batch in batches:
            q0, qd0, us = inputs(q_init, batch)
            for mode in ("forward", "gradient"):
                fns, compile_s, times = {}, {}, {}
                for v, roll in variants.items():
                    fns[v] = _build(roll, mode)
                    compile_s[v] = _time(fns[v], (q0, qd0, us))  # compile + first run
                    times[v] = []
                # calls per measurement: enough for ~20 ms, so microsecond runs are not timer noise
                calls = {v: max(1, int(0.02 / max(_time(fns[v], (q0, qd0, us)), 1e-6))) for v in fns}
                reference, mine = (fns[v](q0, qd0, us) for v in ("closed form", "lagrange"))
                reference, mine = (np.asarray(x[0] if mode == "forward" else x) for x in (reference, mine))
                agree = float(np.max(np.abs(mine - reference)) / max(1.0, float(np.max(np.abs(reference)))))
                for _ in range(repeats):
                    for v in variants:
                        if v == "naive autodiff" and len(times[v]) >= max(3, repeats // 3):
                            continue
                        times[v].append(_time(fns[v], (q0, qd0, us), calls[v]))
                med = {v: float(np.median(t)) for v, t in times.items()}
                row = {"system": name, "batch": batch, "mode": mode, "ms": {v: 1e3 * t for v, t in med.items()},
                       "compile_s": compile_s, "ratio_vs_closed_form": med["lagrange"] / med["closed form"],
                       "ratio_vs_closed_form_remat": med["lagrange"] / med["closed form + remat"],
                       "naive_vs_closed_form": med["naive autodiff"] / med["closed form"],
                       "max_rel_diff_vs_closed_form": agree}
                rows.append(row)
                print(markdown([row]).splitlines()[-1], flush=True)
    return rows


def markdown(rows) -> str:
    out = ["| system | batch | mode | lagrange ms | closed form ms | closed form + remat ms | naive autodiff ms "
           "| lagrange / closed | lagrange / (closed + remat) | naive / closed | compile lagrange / closed s |",
           "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        ms, c = r["ms"], r["compile_s"]
        out.append(f"| {r['system']} | {r['batch']} | {r['mode']} | {ms['lagrange']:.3f} | {ms['closed form']:.3f} | "
                   f"{ms['closed form + remat']:.3f} | {ms['naive autodiff']:.3f} | "
                   f"**{r['ratio_vs_closed_form']:.2f}** | {r['ratio_vs_closed_form_remat']:.2f} | "
                   f"{r['naive_vs_closed_form']:.1f} | {c['lagrange']:.2f} / {c['closed form']:.2f} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="acrobot only, 3 repeats")
    args = ap.parse_args()
    out = outputs(args.quick)[0]
    systems = ["acrobot"] if args.quick else list(SYSTEMS)
    repeats = 3 if args.quick else args.repeats
    rows = run(repeats, (1, 1024), systems)
    table = markdown(rows)
    print(f"\n{table}")
    write_json(os.path.join(out, "derivation_overhead.json"),
               {"rows": rows, "jax": jax.__version__, "backend": jax.default_backend(), "cpus": os.cpu_count()})
    write_text(os.path.join(out, "derivation_overhead.md"), table + "\n")
    print(f"wrote {out}/derivation_overhead.json and .md")


if __name__ == "__main__":
    main()
