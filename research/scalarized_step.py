"""Does evaluating a 3-D tree's step as scalars over a batch-last axis make it fast on the CPU?

    python -m research.scalarized_step      # dm_control's humanoid, about 6 minutes on 2 cores

``research._scalarize`` re-evaluates the jaxpr of one environment's semi-implicit Euler step
(``lagrange.step(tree, q, qd, u, dt, SemiImplicitEuler())``) with every array entry a separate ``(B,)`` array: every
operation is then elementwise over the batch (the batch is the last, contiguous axis), products with structural zeros
and ones are folded at trace time, and the tree's sparsity falls out of the 0/1 path matrices by itself. The rollout
scans that step with the state as ``(n, B)`` arrays. Measured at B = 1024, float64, in one process: scalar
operations traced, trace and compile time, and seconds per env-step of one 2-step call beside the ``jax.vmap``-ed
``lagrange.simulate`` of the same states (the library's path). Writes ``research/results/scalarized_step.json``.
"""

from __future__ import annotations

import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks.trees3d import MODELS, free_flight, states  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402
from research import _scalarize as S  # noqa: E402

B, T = 1024, 2


def main():
    model, tree = free_flight(MODELS["dm_control humanoid"]())
    rng = np.random.default_rng(0)
    q0, qd0 = states(model, rng, B)
    us = rng.uniform(-1, 1, (B, T, model.nu))
    dt = float(model.opt.timestep)
    run = S.scalarize(lambda q, qd, u: lg.step(tree, q, qd, u, dt, lg.SemiImplicitEuler()), q0[0], qd0[0], us[0, 0])

    def rollout(q, qd, u):  # batch last: (nq, B), (nv, B), (T, nu, B)
        def body(c, ut):
            oq, oqd = run(list(c[0]), list(c[1]), list(ut))
            return (jnp.stack(oq), jnp.stack(oqd)), None
        return jax.lax.scan(body, (q, qd), u)[0]

    args = (jnp.asarray(q0.T), jnp.asarray(qd0.T), jnp.asarray(us.transpose(1, 2, 0)))
    t = time.perf_counter()
    lowered = jax.jit(rollout).lower(*args)
    out = dict(model="dm_control humanoid", batch=B, steps=T, scalar_ops=S.COUNT["ops"],
               trace_s=time.perf_counter() - t)
    t = time.perf_counter()
    program = lowered.compile()
    out["compile_s"] = time.perf_counter() - t
    print(out, flush=True)

    def final(q, qd, u):
        tr = lg.simulate(tree, q, qd, u, dt, lg.SemiImplicitEuler(), check=False)
        return tr.q[-1], tr.qd[-1]

    library = jax.jit(jax.vmap(final), compiler_options=lg.compiler_options(tree))
    batch_first = tuple(jnp.asarray(x) for x in (q0, qd0, us))
    for name, fn, a in (("scalarized", program, args), ("vmap", library, batch_first)):
        jax.block_until_ready(fn(*a))
        t = time.perf_counter()
        res = jax.block_until_ready(fn(*a))
        out[f"{name}_us_per_env_step"] = (time.perf_counter() - t) / (B * T) * 1e6
        out[f"{name}_final_q"] = np.asarray(res[0]).T if name == "scalarized" else np.asarray(res[0])
        print(name, out[f"{name}_us_per_env_step"], flush=True)
    out["max_abs_diff_q"] = float(np.max(np.abs(out.pop("scalarized_final_q") - out.pop("vmap_final_q"))))
    write_json("research/results/scalarized_step.json", out, indent=2)
    print(out)


if __name__ == "__main__":
    main()
