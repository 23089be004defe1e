"""Speed: env-steps per second, forward and gradient, against the closed form, Brax, MJX, MuJoCo C, Pinocchio.

    python -m benchmarks.throughput                  # the acrobot table, the n-link scaling sweep, the legged models
    python -m benchmarks.throughput --scaling-only   # only the n-link scaling sweep
    python -m benchmarks.throughput --legged-only    # only the half-cheetah in free flight and the hopper on the ground
    python -m benchmarks.throughput --quick          # reduced sweeps, written under runs/benchmarks/

The acrobot table (:func:`acrobot_main`): ``lagrange.systems.acrobot()``, float64, dt = 0.01, rollouts of ``STEPS``
control steps from random states under random controls, batch 1 to 4096; env-steps per second of the jitted rollout
(forward, final state only) and of the gradient of ``sum(q_T^2 + qd_T^2)`` with respect to the controls by reverse
mode, counting the forward steps covered. Semi-implicit Euler beside Brax generalized, MJX and MuJoCo C's ``Euler``;
RK4 beside the hand-written closed form (``oracles/closed_form.py``) and MuJoCo C's ``RK4``. MuJoCo C runs
``mujoco.rollout`` with 2 threads; Pinocchio's ABA (and its derivatives) is timed per call on one state from Python (it
has no batch API). Compile: seconds of the first call of the batch-1024 functions. The n-link scaling sweep:
:func:`scaling_rows`; the legged models: :func:`legged_main`. The tables, read: ``docs/benchmarks.md``.

Writes ``benchmarks/results/throughput.json`` (acrobot), ``throughput_scaling.json`` and its plot
``docs/img/throughput_scaling.png``, ``throughput_legged.json`` (each ``--...-only`` flag only its own;
``--quick``: ``*_quick.*`` under ``runs/benchmarks/``, not published).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import time

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import asset, gymnasium_model, markdown_table, outputs, save_figure, subplots  # noqa: E402
from benchmarks._engines import MujocoC, brax_rollout, mjx_rollout  # noqa: E402
from benchmarks._timing import median_time  # noqa: E402
from lagrange.interop.mjcf import from_mjcf  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402
from oracles import closed_form as cf  # noqa: E402
from oracles.pinocchio import pinocchio_model  # noqa: E402

DT = 0.01
STEPS = 100
ALTERNATING_ROUNDS = 4
JAX_ENGINES_MAX_N = 4  # MJX and Brax in the scaling sweep: MJX at n = 8 did not finish its first forward call in 150 s
PINOCCHIO = importlib.util.find_spec("pinocchio") is not None  # the bench extra; without it, no Pinocchio columns


def _jax_pair(rollout, argnums=2, compiler_options=None):
    """From one environment's ``rollout(q0, qd0, us) -> (q_T, qd_T)``, the jitted batched forward ``fwd(q0 (B, n),
    qd0 (B, n), us (B, T, m)) -> (q_T, qd_T)`` and gradient of ``sum(q_T^2 + qd_T^2)`` with respect to the controls
    (or the arguments ``argnums``), both compiled with ``compiler_options``."""

    def loss(q0, qd0, us):
        q, qd = rollout(q0, qd0, us)
        return jnp.sum(q**2) + jnp.sum(qd**2)

    return (jax.jit(jax.vmap(rollout), compiler_options=compiler_options),
            jax.jit(jax.vmap(jax.grad(loss, argnums=argnums)), compiler_options=compiler_options))


def lagrange_engine(chain, solver, dt=DT, argnums=2):
    def rollout(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, dt, solver, check=False)
        return tr.q[-1], tr.qd[-1]

    return _jax_pair(rollout, argnums)


def closed_form_engine():
    params = cf.acrobot.Params()

    def rollout(q0, qd0, us):
        q, qd = cf.rollout(cf.acrobot.forward_dynamics, params, q0, qd0, us, DT)
        return q[-1], qd[-1]

    return _jax_pair(rollout)


def mujoco_fd_time(mj, n, repeats=5, best=True):
    """Seconds per call of MuJoCo C's ``mjd_transitionFD`` (one-sided differences, its default ``eps`` of 1e-6) at one
    random state: the step Jacobians d(x_next)/d(x, u) a finite-difference gradient through a rollout needs once per
    env-step (timed from Python on one state, as Pinocchio's)."""
    mujoco = mj.mujoco
    d = mujoco.MjData(mj.model)
    rng = np.random.default_rng(0)
    d.qpos[:], d.qvel[:], d.ctrl[:] = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, mj.model.nu)
    A, B = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, mj.model.nu))
    calls = max(1, 2000 // (2 * n + mj.model.nu))

    def fd():
        for _ in range(calls):
            mujoco.mjd_transitionFD(mj.model, d, 1e-6, False, A, B, None, None)

    return median_time(fd, repeats=repeats, min_time=0.0, best=best) / calls


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


def _inputs(n, m, B, T=STEPS, seed=0):
    rng = np.random.default_rng(seed)
    return (jnp.asarray(rng.uniform(-1, 1, (B, n))), jnp.asarray(rng.uniform(-1, 1, (B, n))),
            jnp.asarray(rng.uniform(-1, 1, (B, T, m))))


def time_jax(fn, args, cpu=False, best=False, repeats=None):
    t, c = time.perf_counter(), time.process_time()
    jax.block_until_ready(fn(*args))
    first, first_cpu = time.perf_counter() - t, time.process_time() - c
    run = median_time(fn, *args, repeats=repeats or (5 if best else 3), min_time=0.05, best=best)
    return (run, first, first_cpu) if cpu else (run, first)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced sweep")
    ap.add_argument("--scaling-only", action="store_true", help="run only the n-link scaling sweep")
    ap.add_argument("--legged-only", action="store_true",
                    help="run only the half-cheetah in free flight and the hopper on the ground")
    args = ap.parse_args(argv)
    results, img = outputs(args.quick)
    suffix = "_quick" if args.quick else ""
    if not (args.scaling_only or args.legged_only):
        acrobot_main([1, 64, 1024] if args.quick else [1, 64, 1024, 4096], args.quick,
                     results / f"throughput{suffix}.json")
    if not args.legged_only:
        scaling_main([2, 4, 8] if args.quick else SCALING_NS, results / f"throughput_scaling{suffix}.json",
                     img / f"throughput_scaling{suffix}.png")
    if not args.scaling_only:
        legged_main(64 if args.quick else 1024, results / f"throughput_legged{suffix}.json")


def _versions(**out):
    """``out`` with the MuJoCo and Pinocchio versions (or why Pinocchio is missing)."""
    import mujoco

    try:
        import pinocchio

        pin = pinocchio.__version__
    except ImportError as err:
        pin = f"not installed: {err}"
    return dict(out, mujoco=mujoco.__version__, pinocchio=pin)


def acrobot_main(batches, quick, path):
    """The acrobot table: every engine at every batch size, the ratios at batch 1024, the first calls' seconds."""
    out = _versions(quick=quick, cpu_count=os.cpu_count(), dt=DT, steps=STEPS, system="acrobot", rows=[], compile=[])
    chain = lg.systems.acrobot()
    engines = {
        ("SemiImplicitEuler", "lagrange"): lambda: lagrange_engine(chain, lg.SemiImplicitEuler()),
        ("SemiImplicitEuler", "brax"): lambda: _jax_pair(brax_rollout(chain, DT)),
        ("SemiImplicitEuler", "mjx"): lambda: _jax_pair(mjx_rollout(chain, DT)),
        ("RK4", "lagrange"): lambda: lagrange_engine(chain, lg.RK4()),
        ("RK4", "closed_form"): closed_form_engine,
    }
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
                out["compile"].append(dict(integrator=integ, engine=name, forward_first_call_s=cf,
                                           gradient_first_call_s=cg))
            print(f"  {integ:17s} {name:12s} B={B:5d} fwd {row['forward_steps_per_s']:.3g}/s "
                  f"grad {row['gradient_steps_per_s']:.3g}/s (first calls {cf:.2f} s, {cg:.2f} s)", flush=True)
    for integ, mjname in (("SemiImplicitEuler", "Euler"), ("RK4", "RK4")):
        mj = MujocoC(chain, DT, mjname)
        for B in batches:
            q0, qd0, us = (np.asarray(x) for x in _inputs(2, 1, B))
            t = median_time(mj.make(q0, qd0, us), repeats=3, min_time=0.05)
            out["rows"].append(dict(integrator=integ, engine="mujoco_c_2threads", batch=B,
                                    forward_steps_per_s=B * STEPS / t, gradient_steps_per_s=None))
            print(f"  {integ:17s} mujoco C     B={B:5d} fwd {B * STEPS / t:.3g}/s", flush=True)
    if PINOCCHIO:
        aba, aba_d = pinocchio_times(pinocchio_model(chain), 2)
        out["pinocchio_acrobot"] = dict(aba_calls_per_s=1 / aba, aba_derivatives_calls_per_s=1 / aba_d)
        print(f"  pinocchio ABA {1 / aba:.3g} calls/s, ABA derivatives {1 / aba_d:.3g} calls/s", flush=True)

    def ratio(integ, other, mode="forward"):  # lagrange's env-steps per second over ``other``'s at batch 1024
        rate = {(r["integrator"], r["engine"]): r[f"{mode}_steps_per_s"] for r in out["rows"] if r["batch"] == 1024}
        return rate[integ, "lagrange"] / rate[integ, other]

    ratios = {
        "forward_vs_brax (SIE, B=1024; target >= 20)": ratio("SemiImplicitEuler", "brax"),
        "forward_vs_mujoco_c_2threads (SIE, B=1024; target >= 10)": ratio("SemiImplicitEuler", "mujoco_c_2threads"),
        "forward_vs_mujoco_c_2threads (RK4, B=1024)": ratio("RK4", "mujoco_c_2threads"),
        "forward_vs_closed_form (RK4, B=1024)": ratio("RK4", "closed_form"),
        "gradient_vs_brax (SIE, B=1024; target >= 10)": ratio("SemiImplicitEuler", "brax", "gradient"),
        "gradient_vs_closed_form (RK4, B=1024)": ratio("RK4", "closed_form", "gradient"),
        "gradient_vs_mjx (SIE, B=1024; target >= 30)": ratio("SemiImplicitEuler", "mjx", "gradient"),
    }
    out["ratios_batch1024"] = ratios
    for k, v in ratios.items():
        print(f"lagrange {k}: {v:.3g}")
    write_json(path, out)
    print(f"wrote {path}")


SCALING_T = 20
SCALING_NS = (2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64)


def _trajectory_error(chain, mj, a):
    """lagrange's batch-1024 rollouts against MuJoCo's (float64, same integrator), over every step of the rollouts
    that stay finite in both: the largest |q - q_MuJoCo|, the largest |q_MuJoCo| (the scale it is measured at) and
    how many of the rollouts stay finite in both; MuJoCo's own rounding sensitivity (the largest change of its
    trajectories when every initial angle moves by one ulp); with Pinocchio installed, the largest |q - q_Pinocchio|
    against Pinocchio's ABA stepped by the same semi-implicit Euler, a third, independent reference."""
    q0, qd0, us = (np.asarray(x) for x in a)
    traj = jax.jit(jax.vmap(lambda q, qd, u: lg.simulate(chain, q, qd, u, DT, lg.SemiImplicitEuler(), check=False).q))
    q = np.asarray(traj(q0, qd0, us))[:, 1:]
    qm = mj.make(q0, qd0, us)()[:, :, 1 : 1 + chain.nv]
    finite = np.all(np.isfinite(q) & np.isfinite(qm), axis=(1, 2))
    if not finite.any():
        return dict(max_abs_q_difference_to_mujoco=float("nan"), max_abs_q=float("nan"), rollouts_finite_in_both=0)
    qm_ulp = mj.make(np.nextafter(q0, np.inf), qd0, us)()[:, :, 1 : 1 + chain.nv]
    both = finite & np.all(np.isfinite(qm_ulp), axis=(1, 2))
    out = dict(max_abs_q_difference_to_mujoco=float(np.max(np.abs(q - qm)[finite])),
               max_abs_q=float(np.max(np.abs(qm[finite]))), rollouts_finite_in_both=int(finite.sum()),
               mujoco_one_ulp_spread=float(np.max(np.abs(qm_ulp - qm)[both])))
    if PINOCCHIO:
        qp = pinocchio_rollouts(pinocchio_model(chain), chain, q0, qd0, us)
        fin = finite & np.all(np.isfinite(qp), axis=(1, 2))
        out["max_abs_q_difference_to_pinocchio"] = float(np.max(np.abs(q - qp)[fin]))
    return out


def pinocchio_rollouts(model, chain, q0, qd0, us):
    """Pinocchio's ABA stepped by semi-implicit Euler from each (q0, qd0) under ``us``: q of shape (B, T, n).

    Its revolute joints turn about +y, ours about -y (``d(phi) = (sin phi, -cos phi)``): the chain is mirror-symmetric,
    so its angles, velocities and torques are ours negated (checked on one call)."""
    import pinocchio as pin

    data = model.createData()
    ours = np.asarray(lg.forward_dynamics(chain, jnp.asarray(q0[0]), jnp.asarray(qd0[0]), jnp.asarray(us[0, 0])))
    if not np.allclose(-pin.aba(model, data, -q0[0], -qd0[0], -us[0, 0]), ours, rtol=1e-9, atol=1e-9):
        raise RuntimeError("Pinocchio's model does not mirror the chain: its ABA disagrees with forward_dynamics")
    out = np.empty(us.shape[:2] + (chain.nv,))
    for b in range(us.shape[0]):
        x, v = -q0[b], -qd0[b]
        for t in range(us.shape[1]):
            v = v + DT * pin.aba(model, data, x, v, -us[b, t])
            x = x + DT * v
            out[b, t] = -x
    return out


def scaling_rows(ns):
    """n-link pendulums (every joint actuated), semi-implicit Euler: cost per env-step against n.

    lagrange forward and gradient at batch 1024 (float64 and float32) and batch 1 (float64), MuJoCo C at batch 1024
    (2 threads) and 1, MJX and Brax (batch 1024, n <= ``JAX_ENGINES_MAX_N``), Pinocchio's ABA and its derivatives and
    MuJoCo C's finite-difference step Jacobians (``mjd_transitionFD``, what a finite-difference gradient through a
    rollout needs once per env-step) per call, each the minimum over 5 timed repeats; lagrange's float64 forward and
    MuJoCo C, at batch 1024 and at batch 1, over 4 more rounds that alternate between the two (a busy spell on a shared
    machine slows both); lagrange's first calls in CPU seconds; the trajectories (:func:`_trajectory_error`)."""
    rows = []
    for n in ns:
        ch = lg.systems.n_link_pendulum(n, gear=1.0)
        row, forward, inputs = dict(n=n), {}, {}
        for tag, B, dtype in (("", 1024, jnp.float64), ("_f32", 1024, jnp.float32), ("_batch1", 1, jnp.float64)):
            chain = jax.tree.map(lambda x: x.astype(dtype) if isinstance(x, jax.Array) else x, ch)
            fwd, grad = lagrange_engine(chain, lg.SemiImplicitEuler())
            a = tuple(x.astype(dtype) for x in _inputs(n, n, B, T=SCALING_T))
            t, _, first_cpu = time_jax(fwd, a, cpu=True, best=True)
            tg, _, gfirst_cpu = time_jax(grad, a, cpu=True, best=True)
            row |= {f"lagrange{tag}_us_per_env_step": t / (B * SCALING_T) * 1e6,
                    f"lagrange{tag}_gradient_us_per_env_step": tg / (B * SCALING_T) * 1e6}
            if not tag:
                row |= dict(lagrange_first_call_cpu_s=first_cpu, lagrange_gradient_first_call_cpu_s=gfirst_cpu)
            forward[tag], inputs[tag] = (lambda fwd=fwd, a=a: fwd(*a)), a  # noqa: E731
        a = inputs[""]
        mj = MujocoC(ch, DT)
        # the ratios to MuJoCo C: both sides timed again in alternating rounds, so that a busy spell on the shared
        # machine slows both rather than one
        t, tm = _alternating(forward[""], mj.make(*(np.asarray(x) for x in a)))
        row["lagrange_us_per_env_step"] = min(row["lagrange_us_per_env_step"], t / (1024 * SCALING_T) * 1e6)
        row["mujoco_c_us_per_env_step"] = tm / (1024 * SCALING_T) * 1e6
        row |= _trajectory_error(ch, mj, a)
        row["mujoco_c_fd_jacobians_us_per_call"] = mujoco_fd_time(mj, n) * 1e6
        mj1 = MujocoC(ch, DT, nthread=1)
        t1, tm1 = _alternating(forward["_batch1"], mj1.make(*(np.asarray(x) for x in inputs["_batch1"])))
        row["lagrange_batch1_us_per_env_step"] = min(row["lagrange_batch1_us_per_env_step"], t1 / SCALING_T * 1e6)
        row["mujoco_c_batch1_us_per_env_step"] = tm1 / SCALING_T * 1e6
        if n <= JAX_ENGINES_MAX_N:
            for name, rollout in (("mjx", mjx_rollout(ch, DT)), ("brax", brax_rollout(ch, DT))):
                fwd, grad = _jax_pair(rollout)
                t, _ = time_jax(fwd, a, best=True)
                tg, _ = time_jax(grad, a, best=True)
                row |= {f"{name}_us_per_env_step": t / (1024 * SCALING_T) * 1e6,
                        f"{name}_gradient_us_per_env_step": tg / (1024 * SCALING_T) * 1e6}
        if PINOCCHIO:
            aba, aba_d = pinocchio_times(pinocchio_model(ch), n, repeats=5, calls=1000, best=True)
            row |= dict(pinocchio_aba_us_per_call=aba * 1e6, pinocchio_aba_derivatives_us_per_call=aba_d * 1e6)
        rows.append(row)
        print(f"  n={n:2d} " + ", ".join(f"{k}={v:.3g}" for k, v in row.items() if k != "n"), flush=True)
    return rows


def _alternating(f, g, rounds=ALTERNATING_ROUNDS):
    """The minimum seconds per call of ``f()`` and of ``g()``, timed in ``rounds`` alternating rounds."""
    tf = tg = float("inf")
    for _ in range(rounds):
        tf = min(tf, median_time(f, repeats=3, min_time=0.05, best=True))
        tg = min(tg, median_time(g, repeats=3, min_time=0.05, best=True))
    return tf, tg


def scaling_fit(rows, n_min=8):
    """Exponents p of least-squares fits t ~ n^p over n >= n_min, and lagrange's ratios to MuJoCo C and Pinocchio."""
    fit = {}
    sel = [r for r in rows if r["n"] >= n_min]
    keys = [k for k in rows[0] if k.endswith(("us_per_env_step", "us_per_call"))] if rows else []
    for key in keys:
        pts = [(r["n"], r[key]) for r in sel if key in r]
        if len(pts) >= 2:
            fit[f"exponent_{key}_n>={n_min}"] = float(np.polyfit(*np.log(np.array(pts)).T, 1)[0])
    for r in rows:
        r["forward_speedup_over_mujoco_c"] = r["mujoco_c_us_per_env_step"] / r["lagrange_us_per_env_step"]
        r["gradient_speedup_over_mujoco_c_fd"] = r["mujoco_c_fd_jacobians_us_per_call"] / r[
            "lagrange_gradient_us_per_env_step"]
        if "pinocchio_aba_derivatives_us_per_call" in r:
            r["gradient_speedup_over_pinocchio_aba_derivatives"] = (
                r["pinocchio_aba_derivatives_us_per_call"] / r["lagrange_gradient_us_per_env_step"])
    goal = [r for r in rows if 4 <= r["n"] <= 32]
    for name, extreme, key, scale in (  # over n = 4 ... 32: a row's key (over its scale), where the rows have it
            ("min_forward_speedup_over_mujoco_c_n4..32 (target >= 5)", min, "forward_speedup_over_mujoco_c", None),
            ("min_gradient_speedup_over_mujoco_c_fd_n4..32", min, "gradient_speedup_over_mujoco_c_fd", None),
            ("min_gradient_speedup_over_pinocchio_aba_derivatives_n4..32 (target >= 3)", min,
             "gradient_speedup_over_pinocchio_aba_derivatives", None),
            ("max_abs_q_difference_to_mujoco_n4..32 (target <= 1e-8)", max, "max_abs_q_difference_to_mujoco", None),
            ("max_relative_q_difference_to_mujoco_n4..32", max, "max_abs_q_difference_to_mujoco", "max_abs_q"),
            ("max_mujoco_one_ulp_spread_n4..32", max, "mujoco_one_ulp_spread", None),
            ("max_abs_q_difference_to_pinocchio_n4..32 (target <= 1e-8)", max, "max_abs_q_difference_to_pinocchio",
             None)):
        if goal and key in goal[0]:
            fit[name] = extreme(r[key] / r[scale] if scale else r[key] for r in goal)
    return fit


def scaling_main(ns, path, plot_path):
    """The n-link scaling sweep: its rows, the fitted exponents and the plot."""
    from lagrange.dynamics import RECURSIVE_MIN

    out = _versions(cpu_count=os.cpu_count(), jax=jax.__version__, dt=DT, steps=SCALING_T,
                    system="n_link_pendulum(n, gear=1.0)", integrator="SemiImplicitEuler", recursive_min=RECURSIVE_MIN)
    out["scaling"] = scaling_rows(ns)
    out["scaling_fit"] = scaling_fit(out["scaling"])
    for k, v in out["scaling_fit"].items():
        print(f"{k}: {v:.3g}")
    _plot_scaling(out["scaling"], plot_path)
    write_json(path, out)
    print(f"wrote {path} and {plot_path}")


def _plot_scaling(rows, path):
    if not rows:
        return
    fig, ax = subplots(figsize=(6.5, 4.5))
    series = (
        ("lagrange_us_per_env_step", "o-", "lagrange forward, batch 1024, per env-step"),
        ("lagrange_gradient_us_per_env_step", "o--", "lagrange gradient, batch 1024, per env-step"),
        ("mujoco_c_us_per_env_step", "^-", "MuJoCo C, 2 threads, batch 1024, per env-step"),
        ("mujoco_c_fd_jacobians_us_per_call", "^--", "MuJoCo C finite-difference Jacobians, per call (Python)"),
        ("mjx_us_per_env_step", "v-", "MJX forward, batch 1024, per env-step"),
        ("mjx_gradient_us_per_env_step", "v--", "MJX gradient, batch 1024, per env-step"),
        ("brax_us_per_env_step", "d-", "Brax forward, batch 1024, per env-step"),
        ("brax_gradient_us_per_env_step", "d--", "Brax gradient, batch 1024, per env-step"),
        ("pinocchio_aba_us_per_call", "s-", "Pinocchio ABA, per call (Python)"),
        ("pinocchio_aba_derivatives_us_per_call", "s--", "Pinocchio ABA derivatives, per call (Python)"),
    )
    for key, style, label in series:
        pts = [(r["n"], r[key]) for r in rows if key in r]
        if pts:
            ax.loglog(*np.array(pts).T, style, label=label, ms=4)
    n = np.array([r["n"] for r in rows], float)
    k = int(np.argmin(np.abs(n - 8)))  # reference slope through lagrange's n = 8 point
    ax.loglog(n, rows[k]["lagrange_us_per_env_step"] * (n / n[k]), "k:", lw=0.8, label="O(n)")
    ax.set(xlabel="links n", ylabel="microseconds", title="cost per step against chain length (float64, SIE)")
    ax.legend(fontsize=6.5)
    ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path, dpi=80)


# the legged models (issues 42 and 43)
LEGGED_T = 20
MJX_CONTACT_GRADIENT_BATCH = 128  # MJX's gradient through contact at batch 1024 ran out of the machine's 23 GB
LEGGED = {  # Gymnasium's model, from_mjcf's limits and contact, MuJoCo's constraints, Brax's model (None: lagrange's)
    "half_cheetah_free_flight": ("half_cheetah", "ignore", "ignore", False, None),
    "hopper_on_the_ground": ("hopper", lg.PenaltyLimits(1e3, 10.0), lg.PenaltyContact(2e4, 1e3, 1e3, 0.9), True,
                             "hopper"),
}


def legged_model(name, constraints, iterations=None):
    """Gymnasium's model ``name`` with MuJoCo's ``Euler``, its constraints (contact, limits) disabled unless
    ``constraints``, its solver's ``iterations`` if given."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(gymnasium_model(name)))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    model.opt.disableflags |= 0 if constraints else mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.opt.iterations = iterations or model.opt.iterations
    return model


def _legged_inputs(chain, model, batch, settle=150):
    """:func:`_inputs`; with contact, the states are Gymnasium's reset (``qpos0``, coordinates and velocities moved by
    up to 5e-3) after ``settle`` steps without control and with 100 times the contact damping (the landing's bounces
    die out): the foot stands on the ground. Also how many states touch the ground in MuJoCo (``ncon > 0``)."""
    import mujoco

    q0, qd0, us = _inputs(chain.nv, chain.m, batch, T=LEGGED_T)
    if chain.contact is not None:
        rng = np.random.default_rng(1)
        q0, qd0 = model.qpos0 + rng.uniform(-5e-3, 5e-3, q0.shape), rng.uniform(-5e-3, 5e-3, qd0.shape)
        damped = eqx.tree_at(lambda c: c.contact.kd, chain, 100 * chain.contact.kd)
        tr = jax.jit(jax.vmap(lambda q, qd: lg.simulate(damped, q, qd, jnp.zeros((settle, chain.m)),
                                                        model.opt.timestep, lg.SemiImplicitEuler())))(q0, qd0)
        q0, qd0 = tr.q[:, -1], tr.qd[:, -1]
    data, touching = mujoco.MjData(model), 0
    for data.qpos[:], data.qvel[:] in zip(np.asarray(q0), np.asarray(qd0)):
        mujoco.mj_forward(model, data)
        touching += data.ncon > 0
    return (q0, qd0, us), int(touching)


def legged_main(batch, path):
    """The half-cheetah in free flight and the hopper on the ground (:data:`LEGGED`): µs per env-step at ``batch``,
    forward and gradient of ``sum(q_T^2 + qd_T^2)`` with respect to the initial state, ``LEGGED_T`` steps of the
    model's timestep; lagrange, MJX (one solver iteration: its reverse mode needs it where constraints are on) and
    Brax generalized (Brax's own hopper, or the chain written by ``to_mjcf``: Brax ignores MuJoCo's disable flags),
    then lagrange and MuJoCo C in alternating rounds."""
    import mujoco

    out = _versions(batch=batch, steps=LEGGED_T, loadavg_start=os.getloadavg(), rows=[])
    for name, (xml, limits, contact, constraints, brax_xml) in LEGGED.items():
        chain = from_mjcf(gymnasium_model(xml), limits=limits, contact=contact)
        model = legged_model(xml, constraints)
        a, touching = _legged_inputs(chain, model, batch)
        brax_file = brax_xml and asset("brax", "envs", "assets", f"{brax_xml}.xml")
        brax = brax_rollout(brax_file or chain, model.opt.timestep)
        # Brax's hopper has no joint reference (MJCF's ref): its qpos is Gymnasium's less Gymnasium's qpos0
        shift = 0.0 if not brax_xml else mujoco.MjModel.from_xml_path(str(brax_file)).qpos0 - model.qpos0
        engines = {"lagrange": lagrange_engine(chain, lg.SemiImplicitEuler(), model.opt.timestep, argnums=(0, 1)),
                   "mjx": _jax_pair(mjx_rollout(legged_model(xml, constraints, iterations=1), DT), (0, 1)),
                   "brax": _jax_pair(lambda q0, qd0, us: brax(q0 + shift, qd0, us), (0, 1))}
        row = dict(model=name, dt=model.opt.timestep, n=chain.nv,
                   contact_points=sum(len(b.contacts) for b in chain.bodies), states_touching_in_mujoco=touching)
        for e, (fwd, grad) in engines.items():
            gb = min(batch, MJX_CONTACT_GRADIENT_BATCH) if e == "mjx" and chain.contact is not None else batch
            repeats = None if e == "lagrange" else 2
            t, first = time_jax(fwd, a, best=True, repeats=repeats)
            tg, gfirst = time_jax(grad, tuple(x[:gb] for x in a), best=True, repeats=repeats)
            row |= {f"{e}_us_per_env_step": t / (batch * LEGGED_T) * 1e6, f"{e}_gradient_batch": gb,
                    f"{e}_gradient_us_per_env_step": tg / (gb * LEGGED_T) * 1e6, f"{e}_first_calls_s": [first, gfirst]}
            print(f"  {name} {e}: {row[f'{e}_us_per_env_step']:.3g} / {row[f'{e}_gradient_us_per_env_step']:.3g} "
                  f"us per env-step (first calls {first:.1f} s, {gfirst:.1f} s)", flush=True)
        # MuJoCo C's 2 threads need both cores (one busy with other work halves them); 1 thread, per core
        mj, mj1 = (MujocoC(model, None, nthread=k).make(*(np.asarray(x) for x in a)) for k in (2, 1))
        t, tm = _alternating(lambda: engines["lagrange"][0](*a), mj)
        t1, tm1 = _alternating(lambda: engines["lagrange"][0](*a), mj1)
        row |= {"lagrange_us_per_env_step": min(row["lagrange_us_per_env_step"], t / (batch * LEGGED_T) * 1e6),
                "mujoco_c_us_per_env_step": tm / (batch * LEGGED_T) * 1e6,
                "mujoco_c_1thread_us_per_env_step": tm1 / (batch * LEGGED_T) * 1e6,
                "forward_speedup_over_mujoco_c (target >= 5)": tm / t,
                "forward_speedup_over_mujoco_c_1thread": tm1 / t1,
                "max_abs_qT_difference_to_mujoco": float(np.max(np.abs(np.asarray(engines["lagrange"][0](*a)[0])
                                                                       - mj()[:, -1, 1 : 1 + chain.nv])))}
        out["rows"].append(row)
    out["loadavg_end"] = os.getloadavg()
    print(markdown_table(out["rows"], list(out["rows"][0])))
    write_json(path, out)
    print(f"wrote {path}")

if __name__ == "__main__":
    main()
