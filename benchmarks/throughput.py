"""Speed: env-steps per second, forward and gradient, against the closed form, Brax, MJX, MuJoCo C, Pinocchio.

    python -m benchmarks.throughput                  # the acrobot table and the n-link scaling sweep
    python -m benchmarks.throughput --scaling-only   # only the n-link scaling sweep
    python -m benchmarks.throughput --quick          # reduced sweeps, written under runs/benchmarks/

The acrobot (``lagrange.systems.acrobot()``), float64 on the CPU, dt = 0.01, rollouts of
``STEPS`` control steps from random states under random controls, batch 1, 64, 1024, 4096.

- forward: env-steps/s = batch x steps / wall time of a jitted rollout (final state only).
- gradient: d/d(controls) of ``sum(q_T^2 + qd_T^2)``, the same rollout differentiated by
  reverse mode (``jax.grad``); env-steps/s counts forward steps covered.
- same integrator, same run: semi-implicit Euler (lagrange ``SemiImplicitEuler``, Brax
  generalized, MuJoCo C ``Euler``, MJX ``Euler``) and RK4 (lagrange ``RK4``, the hand-written closed
  form ``tests/oracles/closed_form.py``, MuJoCo C ``RK4``).
- MuJoCo C runs ``mujoco.rollout`` with 2 threads; Pinocchio's ABA (and its derivatives) is timed
  per call from Python on a single state (it has no batch API), so its numbers are per
  dynamics evaluation, not per env-step of an integrator.
- compile: seconds for the first call (trace + compile + run) of the batch-1024 forward and
  gradient functions.
- scaling: n-link pendulums, n = 2 ... 32, semi-implicit Euler at batch 1024, rollouts of 20 steps:
  lagrange forward and gradient and MuJoCo C per env-step, Pinocchio ABA (and its derivatives)
  per call, each the minimum over 5 timed repeats (robust on a shared machine); the first calls'
  wall and CPU seconds (CPU time is the cost of compiling on a busy
  machine); the exponent of a least-squares fit ``t ~ n^p`` over n >= 8 (the recursive path).

Writes the acrobot table to ``benchmarks/results/throughput.json``, the scaling sweep to
``benchmarks/results/throughput_scaling.json`` and its plot to ``docs/img/throughput_scaling.png``
(``--scaling-only``: only the last two; ``--quick``: ``*_quick.*`` under ``runs/benchmarks/``, not published).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import outputs  # noqa: E402
from benchmarks._timing import block, median_time  # noqa: E402
from lagrange.interop.mjcf import to_mjcf  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402

DT = 0.01
STEPS = 100


def _loss(q, qd):
    return jnp.sum(q**2) + jnp.sum(qd**2)


# ------------------------------------------------------------------------------ JAX engines
# Each factory returns fwd(q0 (B,n), qd0 (B,n), us (B,T,m)) -> (q, qd) and grad(...) -> d/d us.


def _jax_pair(rollout):
    """rollout(q0, qd0, us) for one env -> (qT, qdT); returns jitted batched forward and gradient."""
    fwd = jax.jit(jax.vmap(rollout))

    def loss(q0, qd0, us):
        return _loss(*rollout(q0, qd0, us))

    grad = jax.jit(jax.vmap(jax.grad(loss, argnums=2)))
    return fwd, grad


def lagrange_engine(chain, solver):
    def rollout(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, DT, solver, check=False)
        return tr.q[-1], tr.qd[-1]

    return _jax_pair(rollout)


def closed_form_engine():
    from tests.oracles import closed_form as cf

    params = cf.acrobot.Params()

    def rollout(q0, qd0, us):
        q, qd = cf.rollout(cf.acrobot.forward_dynamics, params, q0, qd0, us, DT)
        return q[-1], qd[-1]

    return _jax_pair(rollout)


def brax_engine(chain):
    from brax.generalized import pipeline
    from brax.io import mjcf as bmjcf

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys = bmjcf.loads(to_mjcf(chain, timestep=DT, integrator="Euler"))

    def rollout(q0, qd0, us):
        state = pipeline.init(sys, q0, qd0)
        state, _ = jax.lax.scan(lambda s, u: (pipeline.step(sys, s, u), None), state, us)
        return state.q, state.qd

    return _jax_pair(rollout)


def mjx_engine(chain, integrator="Euler"):
    import mujoco
    from mujoco import mjx

    mx = mjx.put_model(mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=DT, integrator=integrator)))

    def rollout(q0, qd0, us):
        d = mjx.make_data(mx).replace(qpos=q0, qvel=qd0)
        d, _ = jax.lax.scan(lambda d, u: (mjx.step(mx, d.replace(ctrl=u)), None), d, us)
        return d.qpos, d.qvel

    return _jax_pair(rollout)


# ------------------------------------------------------------------------------ MuJoCo C, Pinocchio


class MujocoC:
    def __init__(self, chain, integrator, nthread=2):
        import mujoco
        import mujoco.rollout as rollout

        self.mujoco, self.rollout = mujoco, rollout
        self.model = mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=DT, integrator=integrator))
        self.datas = [mujoco.MjData(self.model) for _ in range(nthread)]
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mujoco.mj_stateSize(self.model, self.spec)

    def make(self, q0, qd0, us):
        B, n = q0.shape
        x0 = np.zeros((B, self.nstate))
        x0[:, 1 : 1 + n], x0[:, 1 + n : 1 + 2 * n] = q0, qd0
        ctrl = np.asarray(us) if self.model.nu else None
        nstep = us.shape[1]
        state = np.empty((B, nstep, self.nstate))
        return lambda: self.rollout.rollout(self.model, self.datas, x0, ctrl, nstep=nstep, state=state,
                                            persistent_pool=True)


def pinocchio_chain(chain):
    """A Pinocchio model of the same planar chain (revolute joints about y), or None."""
    try:
        import pinocchio as pin
    except ImportError:
        return None
    model = pin.Model()
    parent = 0
    mass, length, com, inertia = (np.asarray(x, float) for x in (chain.mass, chain.length, chain.com, chain.inertia))
    for i in range(chain.n):
        placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, -length[i - 1] if i else 0.0]))
        parent = model.addJoint(parent, pin.JointModelRY(), placement, f"q{i}")
        I = max(inertia[i], 1e-12)
        model.appendBodyToJoint(parent, pin.Inertia(mass[i], np.array([0.0, 0.0, -com[i]]), np.diag([I, I, I])),
                                pin.SE3.Identity())
    model.gravity.linear = np.array([0.0, 0.0, -float(chain.gravity)])
    return model


def pinocchio_times(model, n, repeats=3, calls=2000, best=False):
    import pinocchio as pin

    data = model.createData()
    rng = np.random.default_rng(0)
    q, v, tau = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)

    def aba():
        for _ in range(calls):
            pin.aba(model, data, q, v, tau)

    def aba_d():
        for _ in range(calls // 4):
            pin.computeABADerivatives(model, data, q, v, tau)

    return (median_time(aba, repeats=repeats, min_time=0.0, best=best) / calls,
            median_time(aba_d, repeats=repeats, min_time=0.0, best=best) / (calls // 4))


# ------------------------------------------------------------------------------ measurement


def _inputs(n, m, B, T=STEPS, seed=0):
    rng = np.random.default_rng(seed)
    return (jnp.asarray(rng.uniform(-1, 1, (B, n))), jnp.asarray(rng.uniform(-1, 1, (B, n))),
            jnp.asarray(rng.uniform(-1, 1, (B, T, m))))


def time_jax(fn, args, cpu=False, best=False):
    t, c = time.perf_counter(), time.process_time()
    block(fn(*args))
    first, first_cpu = time.perf_counter() - t, time.process_time() - c
    run = median_time(fn, *args, repeats=5 if best else 3, min_time=0.05, best=best)
    return (run, first, first_cpu) if cpu else (run, first)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced sweep")
    ap.add_argument("--no-mjx", action="store_true")
    ap.add_argument("--max-n", type=int, default=32, help="largest chain in the scaling sweep")
    ap.add_argument("--scaling-only", action="store_true", help="run only the n-link scaling sweep")
    args = ap.parse_args(argv)
    results, img = outputs(args.quick)
    suffix = "_quick" if args.quick else ""
    ns = [n for n in ([2, 4, 8] if args.quick else [2, 4, 8, 12, 16, 20, 24, 32]) if n <= args.max_n]
    if not args.scaling_only:
        acrobot_main([1, 64, 1024] if args.quick else [1, 64, 1024, 4096], args.quick, args.no_mjx,
                     results / f"throughput{suffix}.json")
    scaling_main(ns, results / f"throughput_scaling{suffix}.json", img / f"throughput_scaling{suffix}.png")


def acrobot_main(batches, quick, no_mjx, path):
    """The acrobot table: every engine at every batch size, the ratios at batch 1024, the first calls' seconds."""
    import mujoco

    out = dict(quick=quick, cpu_count=os.cpu_count(), mujoco=mujoco.__version__, dt=DT, steps=STEPS,
               system="acrobot", rows=[], compile=[], pinocchio=None)
    try:
        import pinocchio

        out["pinocchio"] = pinocchio.__version__
    except ImportError as err:
        out["pinocchio"] = f"not installed: {err}"

    chain = lg.systems.acrobot()
    engines = {
        ("SemiImplicitEuler", "lagrange"): lambda: lagrange_engine(chain, lg.SemiImplicitEuler()),
        ("SemiImplicitEuler", "brax"): lambda: brax_engine(chain),
        ("SemiImplicitEuler", "mjx"): lambda: mjx_engine(chain, "Euler"),
        ("RK4", "lagrange"): lambda: lagrange_engine(chain, lg.RK4()),
        ("RK4", "closed_form"): closed_form_engine,
    }
    if no_mjx:
        engines.pop(("SemiImplicitEuler", "mjx"))
    for (integ, name), make in engines.items():
        fwd, grad = make()
        for B in batches:
            if name == "mjx" and B > 1024:
                continue
            a = _inputs(2, 1, B)
            tf, cf = time_jax(fwd, a)
            tg, cg = time_jax(grad, a)
            row = dict(integrator=integ, engine=name, batch=B, forward_steps_per_s=B * STEPS / tf,
                       gradient_steps_per_s=B * STEPS / tg)
            out["rows"].append(row)
            if B == 1024:
                out["compile"].append(dict(integrator=integ, engine=name, forward_first_call_s=cf, gradient_first_call_s=cg))
            print(f"  {integ:17s} {name:12s} B={B:5d} fwd {row['forward_steps_per_s']:.3g}/s "
                  f"grad {row['gradient_steps_per_s']:.3g}/s (first calls {cf:.2f} s, {cg:.2f} s)", flush=True)
    for integ, mjname in (("SemiImplicitEuler", "Euler"), ("RK4", "RK4")):
        mj = MujocoC(chain, mjname)
        for B in batches:
            q0, qd0, us = (np.asarray(x) for x in _inputs(2, 1, B))
            t = median_time(mj.make(q0, qd0, us), repeats=3, min_time=0.05)
            out["rows"].append(dict(integrator=integ, engine="mujoco_c_2threads", batch=B,
                                    forward_steps_per_s=B * STEPS / t, gradient_steps_per_s=None))
            print(f"  {integ:17s} mujoco C     B={B:5d} fwd {B * STEPS / t:.3g}/s", flush=True)
    pm = pinocchio_chain(chain)
    if pm is not None:
        aba, aba_d = pinocchio_times(pm, 2)
        out["pinocchio_acrobot"] = dict(aba_calls_per_s=1 / aba, aba_derivatives_calls_per_s=1 / aba_d)
        print(f"  pinocchio ABA {1 / aba:.3g} calls/s, ABA derivatives {1 / aba_d:.3g} calls/s", flush=True)

    # ratios at batch 1024
    def get(integ, eng, key, B=1024):
        for r in out["rows"]:
            if r["integrator"] == integ and r["engine"] == eng and r["batch"] == B:
                return r[key]
        return None

    lg_sie_f, lg_sie_g = get("SemiImplicitEuler", "lagrange", "forward_steps_per_s"), get("SemiImplicitEuler", "lagrange", "gradient_steps_per_s")
    ratios = {
        "forward_vs_brax (SIE, B=1024; target >= 20)": lg_sie_f / get("SemiImplicitEuler", "brax", "forward_steps_per_s"),
        "forward_vs_mujoco_c_2threads (SIE, B=1024; target >= 10)": lg_sie_f / get("SemiImplicitEuler", "mujoco_c_2threads", "forward_steps_per_s"),
        "forward_vs_mujoco_c_2threads (RK4, B=1024)": get("RK4", "lagrange", "forward_steps_per_s") / get("RK4", "mujoco_c_2threads", "forward_steps_per_s"),
        "forward_vs_closed_form (RK4, B=1024)": get("RK4", "lagrange", "forward_steps_per_s") / get("RK4", "closed_form", "forward_steps_per_s"),
        "gradient_vs_brax (SIE, B=1024; target >= 10)": lg_sie_g / get("SemiImplicitEuler", "brax", "gradient_steps_per_s"),
        "gradient_vs_closed_form (RK4, B=1024)": get("RK4", "lagrange", "gradient_steps_per_s") / get("RK4", "closed_form", "gradient_steps_per_s"),
    }
    if not no_mjx:
        ratios["gradient_vs_mjx (SIE, B=1024; target >= 30)"] = lg_sie_g / get("SemiImplicitEuler", "mjx", "gradient_steps_per_s")
    out["ratios_batch1024"] = ratios
    _print(out)
    write_json(path, out)
    print(f"wrote {path}")


SCALING_T = 20


def scaling_rows(ns):
    """n-link pendulums (every joint actuated), SIE at batch 1024: cost per env-step against n."""
    rows = []
    for n in ns:
        ch = lg.systems.n_link_pendulum(n, gear=1.0)
        fwd, grad = lagrange_engine(ch, lg.SemiImplicitEuler())
        a = _inputs(n, n, 1024, T=SCALING_T)
        steps = 1024 * SCALING_T
        t, first, first_cpu = time_jax(fwd, a, cpu=True, best=True)
        tg, gfirst, gfirst_cpu = time_jax(grad, a, cpu=True, best=True)
        mj = MujocoC(ch, "Euler")
        tm = median_time(mj.make(*(np.asarray(x) for x in a)), repeats=5, min_time=0.05, best=True)
        row = dict(n=n, lagrange_us_per_env_step=t / steps * 1e6, lagrange_gradient_us_per_env_step=tg / steps * 1e6,
                   lagrange_first_call_s=first, lagrange_first_call_cpu_s=first_cpu,
                   lagrange_gradient_first_call_s=gfirst, lagrange_gradient_first_call_cpu_s=gfirst_cpu,
                   mujoco_c_us_per_env_step=tm / steps * 1e6)
        pm = pinocchio_chain(ch)
        if pm is not None:
            aba, aba_d = pinocchio_times(pm, n, repeats=5, calls=1000, best=True)
            row |= dict(pinocchio_aba_us_per_call=aba * 1e6, pinocchio_aba_derivatives_us_per_call=aba_d * 1e6)
        rows.append(row)
        print(f"  n={n:2d} {row}", flush=True)
    return rows


def scaling_fit(rows, n_min=8):
    """Exponents p of least-squares fits t ~ n^p over n >= n_min, and the n = 20 ratios to Pinocchio."""
    fit = {}
    sel = [r for r in rows if r["n"] >= n_min]
    if len(sel) >= 2:
        ln = np.log([r["n"] for r in sel])
        for key in ("lagrange_us_per_env_step", "lagrange_gradient_us_per_env_step", "mujoco_c_us_per_env_step",
                    "pinocchio_aba_us_per_call"):
            if key in sel[0]:
                fit[f"exponent_{key}_n>={n_min}"] = float(np.polyfit(ln, np.log([r[key] for r in sel]), 1)[0])
    for r in rows:
        if r["n"] == 20 and "pinocchio_aba_us_per_call" in r:
            fit["n20_forward_over_pinocchio_aba (target <= 3)"] = r["lagrange_us_per_env_step"] / r["pinocchio_aba_us_per_call"]
            fit["n20_gradient_over_pinocchio_aba_derivatives"] = (
                r["lagrange_gradient_us_per_env_step"] / r["pinocchio_aba_derivatives_us_per_call"])
    return fit


def scaling_main(ns, path, plot_path):
    """The n-link scaling sweep: its rows, the fitted exponents and the plot."""
    import mujoco

    out = dict(cpu_count=os.cpu_count(), mujoco=mujoco.__version__, dt=DT, steps=SCALING_T, batch=1024,
               system="n_link_pendulum(n, gear=1.0)", integrator="SemiImplicitEuler", pinocchio=None)
    try:
        import pinocchio

        out["pinocchio"] = pinocchio.__version__
    except ImportError as err:
        out["pinocchio"] = f"not installed: {err}"
    from lagrange.dynamics import RECURSIVE_MIN

    out["recursive_min"] = RECURSIVE_MIN
    out["scaling"] = scaling_rows(ns)
    out["scaling_fit"] = scaling_fit(out["scaling"])
    _print_scaling(out)
    _plot_scaling(out["scaling"], plot_path)
    write_json(path, out)
    print(f"wrote {path} and {plot_path}")


def _print_scaling(out):
    rows = out["scaling"]
    if not rows:
        return
    cols = [("n", "n", "{:d}"), ("lagrange_us_per_env_step", "lagrange fwd µs/step", "{:.3g}"),
            ("lagrange_gradient_us_per_env_step", "lagrange grad µs/step", "{:.3g}"),
            ("pinocchio_aba_us_per_call", "Pinocchio ABA µs/call", "{:.3g}"),
            ("pinocchio_aba_derivatives_us_per_call", "Pinocchio ABA derivs µs/call", "{:.3g}"),
            ("mujoco_c_us_per_env_step", "MuJoCo C µs/step", "{:.3g}"),
            ("lagrange_first_call_cpu_s", "fwd first call CPU s", "{:.2f}"),
            ("lagrange_gradient_first_call_cpu_s", "grad first call CPU s", "{:.2f}")]
    cols = [c for c in cols if c[0] in rows[0]]
    print("\n| " + " | ".join(c[1] for c in cols) + " |\n|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(f.format(r[k]) for k, _, f in cols) + " |")
    for k, v in out.get("scaling_fit", {}).items():
        print(f"{k}: {v:.3g}")


def _print(out):
    print("\n| integrator | engine | batch | forward env-steps/s | gradient env-steps/s |\n|---|---|---|---|---|")
    for r in out["rows"]:
        g = r["gradient_steps_per_s"]
        print(f"| {r['integrator']} | {r['engine']} | {r['batch']} | {r['forward_steps_per_s']:.3g} | "
              f"{'--' if g is None else f'{g:.3g}'} |")
    print("\n| ratio at batch 1024 | measured |\n|---|---|")
    for k, v in out["ratios_batch1024"].items():
        print(f"| lagrange {k} | {v:.3g} |")
    print("\n| engine | forward first call [s] | gradient first call [s] |\n|---|---|---|")
    for r in out["compile"]:
        print(f"| {r['integrator']} {r['engine']} | {r['forward_first_call_s']:.2f} | {r['gradient_first_call_s']:.2f} |")


def _plot_scaling(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not rows:
        return
    n = np.array([r["n"] for r in rows], float)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.loglog(n, [r["lagrange_us_per_env_step"] for r in rows], "o-", label="lagrange SIE, batch 1024, per env-step")
    if "lagrange_gradient_us_per_env_step" in rows[0]:
        ax.loglog(n, [r["lagrange_gradient_us_per_env_step"] for r in rows], "o--",
                  label="lagrange SIE gradient, batch 1024, per env-step")
    ax.loglog(n, [r["mujoco_c_us_per_env_step"] for r in rows], "^-", label="MuJoCo C Euler, 2 threads, per env-step")
    if "pinocchio_aba_us_per_call" in rows[0]:
        ax.loglog(n, [r["pinocchio_aba_us_per_call"] for r in rows], "s-", label="Pinocchio ABA, per call (Python)")
        ax.loglog(n, [r["pinocchio_aba_derivatives_us_per_call"] for r in rows], "s--",
                  label="Pinocchio ABA derivatives, per call (Python)")
    k = int(np.argmin(np.abs(n - 8)))  # reference slopes through lagrange's n = 8 point
    ref = rows[k]["lagrange_us_per_env_step"]
    ax.loglog(n, ref * (n / n[k]) ** 2, "k:", lw=0.8, label="O(n^2)")
    ax.loglog(n, ref * (n / n[k]), "k--", lw=0.8, label="O(n)")
    ax.set(xlabel="links n", ylabel="microseconds", title="cost per step against chain length")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    main()
