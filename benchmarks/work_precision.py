"""Run time against error: lagrange's solvers, Brax generalized, MuJoCo C and MJX on the same chains.

    python -m benchmarks.work_precision            # full sweep
    python -m benchmarks.work_precision --quick    # reduced sweep (a few minutes on 2 cores), under runs/benchmarks/

Problems (float64, 10 s, controls held over 0.05 s intervals, the same for every engine):

- ``acrobot``: ``lagrange.systems.acrobot()`` from q = (2, 1) rad at rest, u = 0 (chaotic);
- ``double_pendulum``: ``n_link_pendulum(2)`` from q = (2.5, -1.5), qd = (0, 3) (chaotic);
- ``cartpole``: ``cartpole()`` from q = (0, 2.5) under u(t) = 0.5 sin(1.3 t) + 0.3 sin(3.1 t).

Reference: Dopri8 with rtol = atol = 1e-13, checked against Dopri8 at 1e-12 and against fixed-step Dopri8 at
h = 2.5e-4; the larger difference is reported as the reference's own error.

Each configuration is timed for a full 10 s rollout at batch 1 (median of repeats, after compilation) and at batch
1024 (the same initial state 1024 times; timed over the first 0.2 s and scaled by 50 to keep the sweep affordable).
Errors: final-state error max |x(10) - x_ref(10)| over (q, qd), and final energy error
|E(10) - E_ref(10)| / (E_ref(0) - V(0)).

Engines: lagrange (Euler, SemiImplicitEuler, MomentumEuler, RK4, Tsit5, Dopri5, Dopri8 with fixed steps swept;
Tsit5, Dopri5, Dopri8 with rtol = atol swept), Brax generalized (semi-implicit Euler, dt swept), MuJoCo C via
``mujoco.rollout`` with one thread per core (Euler, RK4, implicitfast, dt swept) and MJX (Euler, RK4; dt swept), the
last three on the chain exported by ``lagrange.interop.mjcf.to_mjcf``.

Writes ``benchmarks/results/work_precision.json``, ``benchmarks/results/work_precision.md`` (fastest configuration
per error level and engine) and one plot per problem, ``docs/img/work_precision_<problem>.png`` (``--quick``:
``work_precision_quick.*`` and ``work_precision_<problem>_quick.png`` under ``runs/benchmarks/``, not published).
"""

from __future__ import annotations

import argparse
import os
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import outputs, save_figure, subplots  # noqa: E402
from benchmarks._engines import MujocoC, brax_rollout, mjx_rollout  # noqa: E402
from benchmarks._timing import median_time  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402

DT = 0.05  # control interval [s]
HORIZON = 10.0
T = int(round(HORIZON / DT))
BATCH = 1024
T_BATCH = 4  # intervals timed at batch 1024 (0.2 s, scaled to the 10 s horizon)


def problems():
    t = np.arange(T) * DT
    cart_u = (0.5 * np.sin(1.3 * t) + 0.3 * np.sin(3.1 * t))[:, None]
    return {
        "acrobot": (lg.systems.acrobot(), [2.0, 1.0], [0.0, 0.0], np.zeros((T, 1))),
        "double_pendulum": (lg.systems.n_link_pendulum(2), [2.5, -1.5], [0.0, 3.0], np.zeros((T, 0))),
        "cartpole": (lg.systems.cartpole(), [0.0, 2.5], [0.0, 0.0], cart_u),
    }


def _pair(run):
    """A JAX engine's runners: ``run(q0, qd0, us) -> (q, qd)`` at the end, jitted at batch 1 and vmapped over a batch
    of initial states under the same controls."""
    return jax.jit(run), jax.jit(jax.vmap(run, in_axes=(0, 0, None)))


def lagrange_runner(chain, solver, substeps, tol=None):
    def run(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, DT, solver, substeps, rtol=tol, atol=tol, check=False)
        return tr.q[-1], tr.qd[-1]

    return _pair(run)


def mujoco_runner(chain, substeps, integrator):
    """MuJoCo C, one thread per core: ``run(q0, qd0, us, batch=1) -> (q, qd)`` at the end, from ``batch`` copies of
    the initial state."""
    mj, n = MujocoC(chain, DT / substeps, integrator, nthread=os.cpu_count()), chain.nv

    def run(q0, qd0, us, batch=1):
        d = mj.mujoco.MjData(mj.model)
        d.qpos[:], d.qvel[:] = np.asarray(q0), np.asarray(qd0)
        x0 = np.zeros(mj.mujoco.mj_stateSize(mj.model, mj.spec))
        mj.mujoco.mj_getState(mj.model, d, x0, mj.spec)
        us = np.asarray(us)
        ctrl = np.repeat(us, substeps, axis=0)[None] if mj.model.nu else None
        state, _ = mj.rollout.rollout(mj.model, mj.datas, np.repeat(x0[None], batch, 0), ctrl,
                                      nstep=us.shape[0] * substeps, persistent_pool=True)
        return state[0, -1, 1 : 1 + n], state[0, -1, 1 + n : 1 + 2 * n]

    return run


def _energy(chain, q, qd):
    k, p = lg.energy(chain, jnp.asarray(q), jnp.asarray(qd))
    return float(k + p)


def measure(problem, chain, q0, qd0, us, label, engine, runner, ref, *, substeps=None, tol=None, integrator=None):
    run1, runb = runner if isinstance(runner, tuple) else (runner, None)
    q0j, qd0j, usj = jnp.asarray(q0, float), jnp.asarray(qd0, float), jnp.asarray(us, float)
    t = time.perf_counter()
    q, qd = jax.block_until_ready(run1(q0j, qd0j, usj))
    compile_s = time.perf_counter() - t
    t1 = median_time(run1, q0j, qd0j, usj, repeats=3, min_time=0.02)
    x = np.concatenate([np.asarray(q), np.asarray(qd)])
    err = float(np.max(np.abs(x - ref["x"]))) if np.all(np.isfinite(x)) else float("inf")
    e_err = abs(_energy(chain, q, qd) - ref["E"]) / ref["scale"] if np.all(np.isfinite(x)) else float("inf")
    # batch BATCH, timed over the first T_BATCH intervals and scaled to the full horizon
    ub = usj[:T_BATCH]
    if runb is None:  # MuJoCo C
        tb = median_time(lambda: runner(q0, qd0, ub, batch=BATCH), repeats=3, min_time=0.0, warmup=0)
    else:
        qb, qdb = jnp.tile(q0j, (BATCH, 1)), jnp.tile(qd0j, (BATCH, 1))
        jax.block_until_ready(runb(qb, qdb, ub))
        tb = median_time(runb, qb, qdb, ub, repeats=3, min_time=0.0)
    row = dict(problem=problem, engine=engine, config=label, substeps=substeps,
               h=DT / substeps if substeps else None, tol=tol, integrator=integrator,
               time_batch1_s=t1, time_batch1024_s=tb * T / T_BATCH, first_call_s=compile_s,
               final_state_error=err, energy_error=e_err)
    print(f"  {problem:15s} {engine:8s} {label:28s} t1={t1:.3g}s t1024={row['time_batch1024_s']:.3g}s "
          f"err={err:.2e} Eerr={e_err:.2e}", flush=True)
    return row


def reference(chain, q0, qd0, us):
    q0j, qd0j, usj = jnp.asarray(q0, float), jnp.asarray(qd0, float), jnp.asarray(us, float)

    def final(**kw):
        tr = lg.simulate(chain, q0j, qd0j, usj, DT, lg.Dopri8(), check=True, max_steps=100_000, **kw)
        return np.concatenate([np.asarray(tr.q[-1]), np.asarray(tr.qd[-1])])

    x13 = final(rtol=1e-13, atol=1e-13)
    x12 = final(rtol=1e-12, atol=1e-12)
    xfix = final(substeps=200)
    ref_err = float(max(np.max(np.abs(x13 - x12)), np.max(np.abs(x13 - xfix))))
    n = chain.nv
    rest = float(lg.energy(chain, jnp.zeros(n), jnp.zeros(n))[1])
    scale = _energy(chain, q0j, qd0j) - rest
    return dict(x=x13, E=_energy(chain, x13[:n], x13[n:]), scale=scale, self_error=ref_err,
                vs_rtol_1e_12=float(np.max(np.abs(x13 - x12))), vs_fixed_h_2_5e_4=float(np.max(np.abs(x13 - xfix))))


def sweep(quick: bool):
    if quick:
        k_lg = {"Euler": [16], "SemiImplicitEuler": [16], "MomentumEuler": [16], "RK4": [2, 8, 32], "Tsit5": [8],
                "Dopri5": [8], "Dopri8": [2, 8]}
        tols = {"Dopri5": [1e-6], "Dopri8": [1e-10], "Tsit5": []}
        k_brax, k_mj, k_mjx = [16], [2, 16], [16]
        mj_integrators = ["Euler", "RK4", "implicitfast"]
        mjx_integrators = ["Euler"]
    else:
        k_lg = {"Euler": [4, 16, 64, 256], "SemiImplicitEuler": [4, 16, 64, 256],
                "MomentumEuler": [4, 16, 64, 256], "RK4": [1, 2, 4, 8, 16, 32, 64],
                "Tsit5": [1, 2, 4, 8, 16, 32], "Dopri5": [1, 2, 4, 8, 16, 32], "Dopri8": [1, 2, 4, 8, 16]}
        tols = {"Tsit5": [1e-4, 1e-6, 1e-8, 1e-10], "Dopri5": [1e-4, 1e-6, 1e-8, 1e-10, 1e-12],
                "Dopri8": [1e-6, 1e-8, 1e-10, 1e-12]}
        k_brax, k_mj, k_mjx = [4, 16, 64, 256], [1, 4, 16, 64, 256], [4, 16, 64]
        mj_integrators = ["Euler", "RK4", "implicitfast"]
        mjx_integrators = ["Euler", "RK4"]
    solvers = {name: getattr(lg, name)() for name in k_lg}
    return k_lg, tols, k_brax, k_mj, k_mjx, mj_integrators, mjx_integrators, solvers


def fastest_table(rows, problem, levels=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10)):
    engines = ["lagrange", "brax", "mujoco", "mjx"]
    lines = [f"**{problem}** (final-state error; time for a 10 s rollout at batch 1 / batch 1024)", "",
             "| error <= | " + " | ".join(engines) + " |", "|---|" + "---|" * len(engines)]
    for lev in levels:
        cells = []
        for eng in engines:
            ok = [r for r in rows if r["problem"] == problem and r["engine"] == eng and r["final_state_error"] <= lev]
            if not ok:
                cells.append("--")
                continue
            b1 = min(ok, key=lambda r: r["time_batch1_s"])
            bb = min(ok, key=lambda r: r["time_batch1024_s"])
            cells.append(f"{b1['config']} {b1['time_batch1_s'] * 1e3:.3g} ms / "
                         f"{bb['config']} {bb['time_batch1024_s']:.3g} s")
        lines.append(f"| {lev:.0e} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(rows, problem, ref, path):
    import matplotlib

    fig, axes = subplots(2, 2, figsize=(11, 8))
    groups = {}
    for r in rows:
        if r["problem"] != problem:
            continue
        kind = "adaptive" if r["tol"] else "fixed"
        name = f"{r['engine']} {r['config'].split(' ')[0]}" + (" (adaptive)" if kind == "adaptive" else "")
        groups.setdefault(name, []).append(r)
    markers = {"lagrange": "o", "brax": "s", "mujoco": "^", "mjx": "D"}
    for (name, rs), color in zip(sorted(groups.items()),
                                 matplotlib.colormaps["tab20"](np.linspace(0, 1, max(len(groups), 2)))):
        rs = [r for r in rs if np.isfinite(r["final_state_error"])]
        if not rs:
            continue
        rs.sort(key=lambda r: r["time_batch1_s"])
        ls = "--" if "adaptive" in name else "-"
        for i, (tkey, ekey) in enumerate([("time_batch1_s", "final_state_error"),
                                          ("time_batch1024_s", "final_state_error"),
                                          ("time_batch1_s", "energy_error"), ("time_batch1024_s", "energy_error")]):
            ax = axes[i // 2][i % 2]
            ax.loglog([r[tkey] for r in rs], [max(r[ekey], 1e-16) for r in rs], ls, marker=markers[name.split()[0]],
                      color=color, label=name if i == 0 else None, ms=4)
    titles = ["final-state error, batch 1", "final-state error, batch 1024", "energy error, batch 1",
              "energy error, batch 1024"]
    for ax, title in zip(axes.flat, titles):
        ax.axhline(ref["self_error"], color="grey", lw=0.8, ls=":")
        ax.set(title=title, xlabel="wall time for a 10 s rollout [s]", ylabel="error")
        ax.grid(True, which="both", alpha=0.3)
    fig.legend(loc="center right", fontsize=7)
    fig.suptitle(f"{problem}: run time against error (float64; dotted: reference's own error)")
    save_figure(fig, path, dpi=70, rect=(0, 0, 0.82, 0.97))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced sweep")
    args = ap.parse_args(argv)
    results, img = outputs(args.quick)
    suffix = "_quick" if args.quick else ""
    k_lg, tols, k_brax, k_mj, k_mjx, mj_int, mjx_int, solvers = sweep(args.quick)
    import mujoco

    out = dict(quick=args.quick, cpu_count=os.cpu_count(), device=str(jax.devices()[0]),
               mujoco=mujoco.__version__, dt_control=DT, horizon_s=HORIZON, batch=BATCH, rows=[], references={})
    t0 = time.perf_counter()
    for name, (chain, q0, qd0, us) in problems().items():
        ref = reference(chain, q0, qd0, us)
        out["references"][name] = {k: v for k, v in ref.items() if k != "x"} | {"x": ref["x"].tolist()}
        print(f"{name}: reference self-error {ref['self_error']:.2e}", flush=True)
        rows = out["rows"]
        for sname, ks in k_lg.items():
            for k in ks:
                rows.append(measure(name, chain, q0, qd0, us, f"{sname} h={DT / k:.3g}", "lagrange",
                                    lagrange_runner(chain, solvers[sname], k), ref, substeps=k))
        for sname, ts in tols.items():
            for tol in ts:
                rows.append(measure(name, chain, q0, qd0, us, f"{sname} tol={tol:.0e}", "lagrange",
                                    lagrange_runner(chain, solvers[sname], 1, tol), ref, tol=tol))
        for k in k_brax:
            rows.append(measure(name, chain, q0, qd0, us, f"Euler h={DT / k:.3g}", "brax",
                                _pair(brax_rollout(chain, DT, k)), ref, substeps=k, integrator="Euler"))
        for integ in mj_int:
            for k in k_mj:
                rows.append(measure(name, chain, q0, qd0, us, f"{integ} h={DT / k:.3g}", "mujoco",
                                    mujoco_runner(chain, k, integ), ref, substeps=k, integrator=integ))
        for integ in mjx_int:
            for k in k_mjx:
                rows.append(measure(name, chain, q0, qd0, us, f"{integ} h={DT / k:.3g}", "mjx",
                                    _pair(mjx_rollout(chain, DT, integ, k)), ref, substeps=k, integrator=integ))
        plot(rows, name, ref, img / f"work_precision_{name}{suffix}.png")
    out["total_wall_s"] = time.perf_counter() - t0
    md = ["# Run time against error" + (" (--quick)" if args.quick else ""), "",
          "Fastest configuration per engine reaching each final-state error; time for one 10 s rollout "
          f"at batch 1 / at batch {BATCH} (float64, CPU, {os.cpu_count()} cores shared with other jobs).", ""]
    for name in out["references"]:
        md += [fastest_table(out["rows"], name), "",
               f"reference self-error {out['references'][name]['self_error']:.1e}", ""]
    write_text(results / f"work_precision{suffix}.md", "\n".join(md))
    write_json(results / f"work_precision{suffix}.json", out)
    print("\n".join(md))
    print(f"wrote {results}/work_precision{suffix}.json and .md, {img}/work_precision_<problem>{suffix}.png "
          f"({out['total_wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
