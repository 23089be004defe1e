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
  form ``benchmarks/oracles/closed_form.py``, MuJoCo C ``RK4``).
- MuJoCo C runs ``mujoco.rollout`` with 2 threads; Pinocchio's ABA (and its derivatives) is timed
  per call from Python on a single state (it has no batch API), so its numbers are per
  dynamics evaluation, not per env-step of an integrator.
- compile: seconds for the first call (trace + compile + run) of the batch-1024 forward and
  gradient functions.
- scaling: n-link pendulums, n = 2 ... 64, semi-implicit Euler, rollouts of 20 steps, per env-step: lagrange
  forward and gradient at batch 1024 (float64 and float32) and at batch 1 (float64), MuJoCo C at batch 1024
  (2 threads) and batch 1, MJX and Brax at batch 1024 (n <= 4: MJX at n = 8 did not finish its first forward
  call in 150 s), Pinocchio ABA (and its derivatives) and MuJoCo C's finite-difference step Jacobians
  (``mjd_transitionFD``, what a finite-difference gradient through a rollout needs once per env-step) per call,
  each the minimum over 5 timed repeats (robust on a shared machine; lagrange's float64 forward and MuJoCo C, at
  batch 1024 and at batch 1, over 4 more rounds that alternate between the two); lagrange's first calls in CPU seconds (the
  cost of compiling on a busy machine); the largest difference between lagrange's and MuJoCo's trajectories, how far
  MuJoCo's own move when every initial angle moves by one ulp, and lagrange's against Pinocchio's ABA stepped by the
  same integrator (all 1024 rollouts, in a Python loop); the ratios to MuJoCo C and Pinocchio; the exponent of a least-squares fit ``t ~ n^p`` over n >= 8.

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
ALTERNATING_ROUNDS = 4


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
    from benchmarks.oracles import closed_form as cf

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

        def run():
            self.rollout.rollout(self.model, self.datas, x0, ctrl, nstep=nstep, state=state, persistent_pool=True)
            return state

        return run


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
    ap.add_argument("--max-n", type=int, default=64, help="largest chain in the scaling sweep")
    ap.add_argument("--jax-engines-max-n", type=int, default=4,
                    help="largest chain MJX and Brax are timed on (MJX at n = 8 did not finish its first forward call in 150 s)")
    ap.add_argument("--scaling-only", action="store_true", help="run only the n-link scaling sweep")
    args = ap.parse_args(argv)
    results, img = outputs(args.quick)
    suffix = "_quick" if args.quick else ""
    ns = [n for n in ([2, 4, 8] if args.quick else SCALING_NS) if n <= args.max_n]
    if not args.scaling_only:
        acrobot_main([1, 64, 1024] if args.quick else [1, 64, 1024, 4096], args.quick, args.no_mjx,
                     results / f"throughput{suffix}.json")
    scaling_main(ns, results / f"throughput_scaling{suffix}.json", img / f"throughput_scaling{suffix}.png",
                 args.jax_engines_max_n)


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
    qm = mj.make(q0, qd0, us)()[:, :, 1 : 1 + chain.n]
    finite = np.all(np.isfinite(q) & np.isfinite(qm), axis=(1, 2))
    if not finite.any():
        return dict(max_abs_q_difference_to_mujoco=float("nan"), max_abs_q=float("nan"), rollouts_finite_in_both=0)
    qm_ulp = mj.make(np.nextafter(q0, np.inf), qd0, us)()[:, :, 1 : 1 + chain.n]
    both = finite & np.all(np.isfinite(qm_ulp), axis=(1, 2))
    out = dict(max_abs_q_difference_to_mujoco=float(np.max(np.abs(q - qm)[finite])),
               max_abs_q=float(np.max(np.abs(qm[finite]))), rollouts_finite_in_both=int(finite.sum()),
               mujoco_one_ulp_spread=float(np.max(np.abs(qm_ulp - qm)[both])))
    model = pinocchio_chain(chain)
    if model is not None:
        qp = pinocchio_rollouts(model, chain, q0, qd0, us)
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
    out = np.empty(us.shape[:2] + (chain.n,))
    for b in range(us.shape[0]):
        x, v = -q0[b], -qd0[b]
        for t in range(us.shape[1]):
            v = v + DT * pin.aba(model, data, x, v, -us[b, t])
            x = x + DT * v
            out[b, t] = -x
    return out


def scaling_rows(ns, jax_engines_max_n=4):
    """n-link pendulums (every joint actuated), semi-implicit Euler: cost per env-step against n.

    lagrange forward and gradient at batch 1024 (float64 and float32) and batch 1 (float64), MuJoCo C at batch 1024
    (2 threads) and 1, MJX and Brax (batch 1024, n <= ``jax_engines_max_n``), Pinocchio's ABA and its derivatives per
    call; lagrange's first calls in CPU seconds; the largest difference of lagrange's and MuJoCo's trajectories."""
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
        mj = MujocoC(ch, "Euler")
        # the ratios to MuJoCo C: both sides timed again in alternating rounds, so that a busy spell on the shared
        # machine slows both rather than one
        t, tm = _alternating(forward[""], mj.make(*(np.asarray(x) for x in a)))
        row["lagrange_us_per_env_step"] = min(row["lagrange_us_per_env_step"], t / (1024 * SCALING_T) * 1e6)
        row["mujoco_c_us_per_env_step"] = tm / (1024 * SCALING_T) * 1e6
        row |= _trajectory_error(ch, mj, a)
        row["mujoco_c_fd_jacobians_us_per_call"] = mujoco_fd_time(mj, n) * 1e6
        mj1 = MujocoC(ch, "Euler", nthread=1)
        t1, tm1 = _alternating(forward["_batch1"], mj1.make(*(np.asarray(x) for x in inputs["_batch1"])))
        row["lagrange_batch1_us_per_env_step"] = min(row["lagrange_batch1_us_per_env_step"], t1 / SCALING_T * 1e6)
        row["mujoco_c_batch1_us_per_env_step"] = tm1 / SCALING_T * 1e6
        if n <= jax_engines_max_n:
            for name, make in (("mjx", lambda: mjx_engine(ch, "Euler")), ("brax", lambda: brax_engine(ch))):
                fwd, grad = make()
                t, _ = time_jax(fwd, a, best=True)
                tg, _ = time_jax(grad, a, best=True)
                row |= {f"{name}_us_per_env_step": t / (1024 * SCALING_T) * 1e6,
                        f"{name}_gradient_us_per_env_step": tg / (1024 * SCALING_T) * 1e6}
        pm = pinocchio_chain(ch)
        if pm is not None:
            aba, aba_d = pinocchio_times(pm, n, repeats=5, calls=1000, best=True)
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
    if goal:
        fit["min_forward_speedup_over_mujoco_c_n4..32 (target >= 5)"] = min(r["forward_speedup_over_mujoco_c"]
                                                                             for r in goal)
        fit["min_gradient_speedup_over_mujoco_c_fd_n4..32"] = min(r["gradient_speedup_over_mujoco_c_fd"] for r in goal)
        if "gradient_speedup_over_pinocchio_aba_derivatives" in goal[0]:
            fit["min_gradient_speedup_over_pinocchio_aba_derivatives_n4..32 (target >= 3)"] = min(
                r["gradient_speedup_over_pinocchio_aba_derivatives"] for r in goal)
        fit["max_abs_q_difference_to_mujoco_n4..32 (target <= 1e-8)"] = max(r["max_abs_q_difference_to_mujoco"]
                                                                             for r in goal)
        fit["max_relative_q_difference_to_mujoco_n4..32"] = max(r["max_abs_q_difference_to_mujoco"] / r["max_abs_q"]
                                                                 for r in goal)
        fit["max_mujoco_one_ulp_spread_n4..32"] = max(r["mujoco_one_ulp_spread"] for r in goal)
        if "max_abs_q_difference_to_pinocchio" in goal[0]:
            fit["max_abs_q_difference_to_pinocchio_n4..32 (target <= 1e-8)"] = max(
                r["max_abs_q_difference_to_pinocchio"] for r in goal)
    return fit


def scaling_main(ns, path, plot_path, jax_engines_max_n=4):
    """The n-link scaling sweep: its rows, the fitted exponents and the plot."""
    import mujoco

    out = dict(cpu_count=os.cpu_count(), mujoco=mujoco.__version__, jax=jax.__version__, dt=DT, steps=SCALING_T,
               system="n_link_pendulum(n, gear=1.0)", integrator="SemiImplicitEuler", pinocchio=None)
    try:
        import pinocchio

        out["pinocchio"] = pinocchio.__version__
    except ImportError as err:
        out["pinocchio"] = f"not installed: {err}"
    from lagrange.dynamics import RECURSIVE_MIN

    out["recursive_min"] = RECURSIVE_MIN
    out["scaling"] = scaling_rows(ns, jax_engines_max_n)
    out["scaling_fit"] = scaling_fit(out["scaling"])
    _print_scaling(out)
    _plot_scaling(out["scaling"], plot_path)
    write_json(path, out)
    print(f"wrote {path} and {plot_path}")


SCALING_COLUMNS = (
    ("n", "n", "{:d}"),
    ("lagrange_us_per_env_step", "lagrange forward", "{:.3g}"),
    ("lagrange_gradient_us_per_env_step", "lagrange gradient", "{:.3g}"),
    ("mujoco_c_us_per_env_step", "MuJoCo C", "{:.3g}"),
    ("forward_speedup_over_mujoco_c", "forward ÷ MuJoCo C", "{:.1f}×"),
    ("pinocchio_aba_us_per_call", "Pinocchio ABA", "{:.3g}"),
    ("pinocchio_aba_derivatives_us_per_call", "Pinocchio ABA derivatives", "{:.3g}"),
    ("gradient_speedup_over_pinocchio_aba_derivatives", "gradient ÷ ABA derivatives", "{:.1f}×"),
    ("mujoco_c_fd_jacobians_us_per_call", "MuJoCo C finite-difference Jacobians", "{:.3g}"),
    ("gradient_speedup_over_mujoco_c_fd", "gradient ÷ MuJoCo C finite differences", "{:.1f}×"),
    ("mjx_us_per_env_step", "MJX forward", "{:.3g}"),
    ("mjx_gradient_us_per_env_step", "MJX gradient", "{:.3g}"),
    ("brax_us_per_env_step", "Brax forward", "{:.3g}"),
    ("brax_gradient_us_per_env_step", "Brax gradient", "{:.3g}"),
    ("lagrange_f32_us_per_env_step", "lagrange float32 forward", "{:.3g}"),
    ("lagrange_f32_gradient_us_per_env_step", "lagrange float32 gradient", "{:.3g}"),
    ("lagrange_batch1_us_per_env_step", "lagrange batch 1 forward", "{:.3g}"),
    ("lagrange_batch1_gradient_us_per_env_step", "lagrange batch 1 gradient", "{:.3g}"),
    ("mujoco_c_batch1_us_per_env_step", "MuJoCo C batch 1", "{:.3g}"),
    ("lagrange_first_call_cpu_s", "forward compile (CPU s)", "{:.2f}"),
    ("lagrange_gradient_first_call_cpu_s", "gradient compile (CPU s)", "{:.2f}"),
    ("max_abs_q_difference_to_mujoco", "max abs q − MuJoCo's", "{:.1e}"),
    ("mujoco_one_ulp_spread", "MuJoCo's own 1-ulp spread", "{:.1e}"),
    ("max_abs_q_difference_to_pinocchio", "max abs q − Pinocchio's", "{:.1e}"),
    ("max_abs_q", "max abs q", "{:.3g}"),
    ("rollouts_finite_in_both", "rollouts finite in both", "{:d}"),
)


def _print_scaling(out):
    rows = out["scaling"]
    if not rows:
        return
    cols = [c for c in SCALING_COLUMNS if any(c[0] in r for r in rows)]
    print("\n| " + " | ".join(c[1] for c in cols) + " |\n|" + "---:|" * len(cols))
    for r in rows:
        print("| " + " | ".join(f.format(r[k]) if k in r else "—" for k, _, f in cols) + " |")
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
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
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
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    main()
