"""Numerical stability sweeps: energy drift, random stress states, float32 vs float64, gradients, contact.

    python -m benchmarks.stability                    # the full sweep (about 5 minutes on 2 cores)
    python -m benchmarks.stability --quick            # reduced sweep (~1-2 minutes), written under runs/benchmarks/
    python -m benchmarks.stability --adaptive-only    # part 2b alone (about 2 minutes; with --quick, under 1)
    python -m benchmarks.stability --contact-only     # part 5 alone (about 1.5 minutes)

1. Energy drift of the conservative acrobot and double pendulum over 1e5 steps for each solver.
2. 10,000 random initial states (speeds up to 50 rad/s, mass ratios up to 1e3 within a chain, chains of 2 to 20
   links), RK4 at dt = 1e-3 for 0.5 s: non-finite trajectories counted, whether ``simulate(check=True)`` would report
   each (its final state is non-finite), the energy error before the blow-up, and how many survive with 8 substeps.
2b. The error-controlled mode on the first states of the same batch, chains of 3 or more links: ``simulate``'s
   adaptive Tsit5 (rtol = atol = 1e-8, ``max_steps`` = 4096 per 1 ms interval), 0.5 s: how many finish, how many are
   stopped by ``max_steps``, their energy error, steps and wall time, beside RK4 at 1 ms on the same states.
3. float32 against float64: the time at which trajectories part (by 0.1 rad) per system, beside two float64 runs
   whose initial angles differ by 1e-7 rad.
4. The gradient norm of a final-state loss with respect to the controls against the horizon for the acrobot,
   float32 and float64 (plot).
5. Gymnasium's hopper and half-cheetah dropped on the ground (penalty contact and limits): the largest stable
   fixed step of semi-implicit Euler against the contact stiffness, the energy at two steps, Tsit5 with error
   control through the impacts (:func:`contact_drops`; plot of the hopper's drop).

Writes ``benchmarks/results/stability.json`` and the plots ``docs/img/stability_gradients.png`` and
``docs/img/hopper_drop.png`` (``--quick``: ``*_quick.*`` under ``runs/benchmarks/``, not published);
``--adaptive-only`` and ``--contact-only`` replace only their key of that JSON (``adaptive_stress``, ``contact``).
Energy errors are relative to ``E0 - V(q = 0)``, the energy above the chain hanging at rest.
"""

from __future__ import annotations

import argparse
import json
import time

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import gymnasium_model, markdown_table, outputs, save_figure, subplots  # noqa: E402
from benchmarks._timing import median_time  # noqa: E402
from lagrange.chain import Chain, Link  # noqa: E402
from lagrange.interop.mjcf import from_mjcf  # noqa: E402
from lagrange.kinematics import contact_point_positions  # noqa: E402
from optim.checkpoint import write_json  # noqa: E402


def _rollout(chain, q0, qd0, dt, solver, steps, substeps=1):
    controls = None if chain.m == 0 else jnp.zeros((steps, chain.m), jnp.asarray(q0).dtype)
    return lg.simulate(chain, q0, qd0, controls, dt, solver, substeps,
                       steps=steps if chain.m == 0 else None, check=False)


def energy_drift(steps: int):
    systems = {"acrobot": lg.systems.acrobot(), "double_pendulum": lg.systems.n_link_pendulum(2)}
    configs = [(lg.Euler(), 1e-3), (lg.SemiImplicitEuler(), 1e-3), (lg.SemiImplicitEuler(), 1e-4),
               (lg.MomentumEuler(), 1e-3), (lg.MomentumEuler(), 5e-4), (lg.RK4(), 1e-3), (lg.RK4(), 5e-4),
               (lg.Tsit5(), 1e-3), (lg.Dopri5(), 1e-3), (lg.Dopri8(), 1e-3), (lg.Dopri8(), 1e-2)]
    q0, qd0 = jnp.array([2.0, 1.0]), jnp.zeros(2)
    rows = []
    for sname, chain in systems.items():
        for solver, dt in configs:
            @jax.jit
            def run(q0, qd0):
                tr = _rollout(chain, q0, qd0, dt, solver, steps)
                kin, pot = lg.energy(chain, tr.q, tr.qd)
                e = kin + pot
                rest = lg.energy(chain, jnp.zeros(2), jnp.zeros(2))[1]
                return (e - e[0]) / (e[0] - rest)

            t = time.perf_counter()
            err = np.abs(np.asarray(run(q0, qd0)))
            wall = time.perf_counter() - t
            h = steps // 2
            rows.append(dict(system=sname, solver=type(solver).__name__, dt=dt, steps=steps, horizon_s=steps * dt,
                             max=float(err.max()), first_half=float(err[: h + 1].max()),
                             second_half=float(err[h:].max()), final=float(err[-1]), wall_s=wall))
    return rows


def _batch(n, size, rng):
    mass = 10.0 ** rng.uniform(-1.5, 1.5, (size, n))
    length = 10.0 ** rng.uniform(-1.0, 0.0, (size, n))
    q = rng.uniform(-np.pi, np.pi, (size, n))
    qd = rng.uniform(-50.0, 50.0, (size, n))
    return tuple(jnp.asarray(x) for x in (mass, length, q, qd))


def _rods(base, mass, length):
    """``base`` (an n-link pendulum) with uniform rods of these masses and lengths: a chain of the stress batch."""
    return Chain([Link("revolute", mass[i], length[i]) for i in range(base.nv)])


def _energy_error(chain, q, qd):
    """``|E(t) - E(0)| / (E(0) - V(q = 0))`` at each row of a trajectory ``q, qd`` (shape ``(T + 1, n)``)."""
    kin, pot = lg.energy(chain, q, qd)
    rest = lg.energy(chain, jnp.zeros(chain.nq), jnp.zeros(chain.nv))[1]
    return jnp.abs(kin + pot - kin[0] - pot[0]) / (kin[0] + pot[0] - rest)


def _stress_fn(n, dt, steps, substeps):
    base = lg.systems.n_link_pendulum(n)

    def one(mass, length, q, qd):
        chain = _rods(base, mass, length)
        tr = _rollout(chain, q, qd, dt, lg.RK4(), steps, substeps)
        finite = jnp.all(jnp.isfinite(tr.q), -1) & jnp.all(jnp.isfinite(tr.qd), -1)
        rel = _energy_error(chain, tr.q, tr.qd)
        qdd0 = lg.forward_dynamics(chain, q, qd)
        peak = jnp.max(jnp.where(finite[:, None], jnp.abs(tr.qd), 0.0))
        # a run-away state's angles pass ~7e15 rad, where their sines (and its energy) are NaN by design: such a
        # state (moving at 1e30 rad/s and more) counts as an unbounded energy error
        rel = jnp.where(jnp.isnan(rel), jnp.inf, rel)
        return (jnp.all(finite), finite[-1], jnp.max(jnp.where(finite, rel, 0.0)),
                jnp.all(jnp.isfinite(qdd0)), peak * dt / substeps)

    return jax.jit(jax.vmap(one))


def stress(n: int, states: int, dt=1e-3, steps=500, rerun_max=200):
    """The fixed-step sweep's row for ``states`` random n-link chains and states (seed ``n``)."""
    mass, length, q, qd = _batch(n, states, np.random.default_rng(n))
    t = time.perf_counter()
    ok, final_ok, rel, fd_ok, wh = (np.asarray(x) for x in _stress_fn(n, dt, steps, 1)(mass, length, q, qd))
    wall = time.perf_counter() - t
    bad = np.flatnonzero(~ok)
    good = ok & (rel <= 1e-2)
    row = dict(n=n, states=states, nonfinite=int(bad.size),
               unreported=int(np.sum(~ok & final_ok)),  # non-finite somewhere, finite at the end
               fd_nonfinite_at_start=int(np.sum(~fd_ok)),
               min_energy_error_before_blowup=float(rel[bad].min()) if bad.size else None,
               finite_energy_error_gt_1e_2=int(np.sum(ok & (rel > 1e-2))),
               accurate=int(good.sum()),
               median_peak_speed_x_h_accurate=float(np.median(wh[good])) if good.any() else None,
               median_peak_speed_x_h_inaccurate=float(np.median(wh[ok & ~good])) if (ok & ~good).any() else None,
               wall_s=wall)
    if bad.size:
        sub, bad = 8, bad[:rerun_max]  # re-run (at most rerun_max of) the failures with dt / 8
        ok8, _, rel8, _, _ = (np.asarray(x) for x in _stress_fn(n, dt, steps, sub)(
            mass[bad], length[bad], q[bad], qd[bad]))
        row["rerun_with_8_substeps"] = int(bad.size)
        row["nonfinite_with_8_substeps"] = int((~ok8).sum())
        row["of_those_energy_error_le_1e_2"] = int(np.sum(ok8 & (rel8 <= 1e-2)))
    print(f"  stress n={n:2d}: {row}", flush=True)
    return row


def _adaptive_rollout(chain, q0, qd0, dt, steps, rtol, atol, max_steps):
    """``lg.simulate(chain, q0, qd0, None, dt, lg.Tsit5(), steps=steps, rtol=rtol, atol=atol, max_steps=max_steps)``
    through the same ``diffrax.diffeqsolve`` per interval, but with ``throw=False``: an interval that fails (reaches
    ``max_steps``) holds the state to the end instead of raising, and diffrax's step counts are kept.

    Returns ``(q, qd, accepted, rejected, busiest, max_steps_hit, failed)``: the states at the interval ends,
    ``(steps + 1, n)``; the accepted and rejected steps in all; the most steps one interval took; whether an interval
    reached ``max_steps``; whether one was not successful at all."""
    u = jnp.zeros((chain.m,), q0.dtype)
    term = diffrax.ODETerm(lambda t, y, u: (y[1], lg.forward_dynamics(chain, y[0], y[1], u, check=False)))
    controller = diffrax.PIDController(rtol=rtol, atol=atol)

    def solve(y):
        sol = diffrax.diffeqsolve(term, lg.Tsit5(), 0.0, dt, dt, y, args=u, stepsize_controller=controller,
                                  saveat=diffrax.SaveAt(t1=True), max_steps=max_steps, throw=False)
        return ((sol.ys[0][0], sol.ys[1][0]), sol.stats["num_accepted_steps"], sol.stats["num_rejected_steps"],
                sol.result == diffrax.RESULTS.max_steps_reached, sol.result != diffrax.RESULTS.successful)

    def hold(y):
        return y, 0, 0, False, False

    def body(carry, _):
        y, accepted, rejected, busiest, hit, failed = carry
        y, a, r, h, f = jax.lax.cond(failed, hold, solve, y)
        return (y, accepted + a, rejected + r, jnp.maximum(busiest, a + r), hit | h, failed | f), y

    zero = jnp.zeros((), int)
    (_, accepted, rejected, busiest, hit, failed), (qs, qds) = jax.lax.scan(
        body, ((q0, qd0), zero, zero, zero, False, False), None, length=steps)
    q, qd = jnp.concatenate([q0[None], qs]), jnp.concatenate([qd0[None], qds])
    return q, qd, accepted, rejected, busiest, hit, failed


def _adaptive_fn(n, dt, steps, rtol, atol, max_steps):
    """Jitted: for each n-link stress state ``(mass, length, q, qd)``, one after the other (under ``vmap`` every
    interval would wait for its slowest state), ``(final state finite, max_steps_hit, failed, largest energy error,
    accepted, rejected, busiest)`` of its :func:`_adaptive_rollout`."""
    base = lg.systems.n_link_pendulum(n)

    def one(x):
        mass, length, q0, qd0 = x
        chain = _rods(base, mass, length)
        q, qd, accepted, rejected, busiest, hit, failed = _adaptive_rollout(chain, q0, qd0, dt, steps, rtol, atol,
                                                                           max_steps)
        finite = jnp.all(jnp.isfinite(q[-1])) & jnp.all(jnp.isfinite(qd[-1]))
        return finite, hit, failed, jnp.max(_energy_error(chain, q, qd)), accepted, rejected, busiest

    return jax.jit(lambda *xs: jax.lax.map(one, xs))


def _median_max(x, kind=float):
    """``(median, max)`` of the array ``x`` as ``kind`` (``int`` for step counts), ``(None, None)`` when it is empty."""
    return (kind(np.median(x)), kind(np.max(x))) if x.size else (None, None)


def adaptive_stress(states, per, dt=1e-3, steps=500, rtol=1e-8, atol=1e-8, max_steps=4096):
    """The error-controlled mode on the first ``states[n]`` of the ``per`` states :func:`stress` draws for each chain
    size ``n``, beside RK4 at ``dt`` on the same states. Per size: how many finish (no interval failed, final state
    finite), stop at ``max_steps`` or end non-finite; the finished ones' largest energy error and solver steps
    (accepted + rejected), median and worst; the busiest interval's steps; the wall time per trajectory (compile
    excluded); how many states RK4 turns non-finite, and how many of those finish here."""
    rows = []
    for n, k in states.items():
        mass, length, q, qd = (x[:k] for x in _batch(n, per, np.random.default_rng(n)))
        rk4_ok, _, rk4_rel, _, _ = (np.asarray(x) for x in _stress_fn(n, dt, steps, 1)(mass, length, q, qd))
        t = time.perf_counter()
        run = _adaptive_fn(n, dt, steps, rtol, atol, max_steps).lower(mass, length, q, qd).compile()
        compile_s = time.perf_counter() - t
        t = time.perf_counter()
        out = jax.block_until_ready(run(mass, length, q, qd))
        wall = time.perf_counter() - t
        finite, hit, failed, rel, accepted, rejected, busiest = (np.asarray(x) for x in out)
        done = finite & ~failed
        energy_median, energy_max = _median_max(rel[done])
        steps_median, steps_max = _median_max((accepted + rejected)[done], int)
        row = dict(n=n, states=k, finished=int(done.sum()), stopped_by_max_steps=int(hit.sum()),
                   stopped_otherwise=int(np.sum(failed & ~hit)), nonfinite=int(np.sum(~finite & ~failed)),
                   energy_error_median=energy_median, energy_error_max=energy_max,
                   steps_median=steps_median, steps_max=steps_max,
                   rejected_median=_median_max(rejected[done], int)[0], busiest_interval_steps=int(busiest.max()),
                   wall_s_per_trajectory=wall / k, compile_s=compile_s,
                   rk4_nonfinite=int(np.sum(~rk4_ok)), rk4_nonfinite_finished=int(np.sum(~rk4_ok & done)),
                   rk4_energy_error_le_1e_2=int(np.sum(rk4_ok & (rk4_rel <= 1e-2))))
        rows.append(row)
        print(f"  adaptive stress n={n:2d}: {row}", flush=True)
    return dict(solver="Tsit5", rtol=rtol, atol=atol, max_steps_per_interval=max_steps, dt=dt, steps=steps,
                horizon_s=steps * dt, states_drawn_per_size=per, rows=rows)


def parting(dt=1e-3, steps=30_000, tol=0.1):
    cases = {
        "pendulum": (lg.systems.pendulum(), [2.0]),
        "cartpole": (lg.systems.cartpole(), [0.0, 2.0]),
        "double_cartpole": (lg.systems.double_cartpole(), [0.0, 2.0, 1.0]),
        "acrobot": (lg.systems.acrobot(), [2.0, 1.0]),
        "double_pendulum": (lg.systems.n_link_pendulum(2), [2.0, 1.0]),
        "double_pendulum_small": (lg.systems.n_link_pendulum(2), [0.2, 0.1]),
        "5_link_pendulum": (lg.systems.n_link_pendulum(5), [2.0, 1.0, 0.5, 0.2, 0.1]),
    }
    rows = []
    for name, (chain, q0) in cases.items():
        q0 = jnp.asarray(q0, jnp.float64)
        z = jnp.zeros_like(q0)
        run = jax.jit(lambda c, q, qd: _rollout(c, q, qd, dt, lg.RK4(), steps).q)
        ref = np.asarray(run(chain, q0, z))

        def part(x):
            gap = np.max(np.abs(np.asarray(x, np.float64) - ref), axis=1)
            i = int(np.argmax(gap > tol))
            return (i * dt if gap[i] > tol else None), float(gap[-1])

        t32, g32 = part(run(lg.astype(chain, jnp.float32), q0.astype(jnp.float32), z.astype(jnp.float32)))
        tp, gp = part(run(chain, q0 + 1e-7, z))
        rows.append(dict(system=name, q0=np.asarray(q0).tolist(), horizon_s=steps * dt,
                         float32_parting_s=t32, float32_final_gap=g32,
                         perturbed_1e_7_parting_s=tp, perturbed_final_gap=gp))
        print(f"  parting {name}: float32 {t32} s, 1e-7 perturbation {tp} s", flush=True)
    return rows


def gradient_growth(horizons, dt=0.01):
    chain64 = lg.systems.acrobot()
    rows = []
    for dtype in (jnp.float64, jnp.float32):
        chain = chain64 if dtype == jnp.float64 else lg.astype(chain64, jnp.float32)
        q0 = jnp.array([2.0, 1.0], dtype)
        qd0 = jnp.zeros(2, dtype)

        def loss(u):
            tr = lg.simulate(chain, q0, qd0, u, dt, lg.RK4(), check=False)
            return jnp.sum(tr.q[-1] ** 2) + jnp.sum(tr.qd[-1] ** 2)

        g = jax.jit(jax.grad(loss))
        for T in horizons:
            grad = np.asarray(g(jnp.zeros((T, 1), dtype)), np.float64)
            rows.append(dict(dtype=jnp.dtype(dtype).name, steps=T, horizon_s=T * dt,
                             grad_norm=float(np.linalg.norm(grad)), finite=bool(np.all(np.isfinite(grad))),
                             _grad=grad))
    by = {(r["dtype"], r["steps"]): r.pop("_grad") for r in rows}
    for r in rows:
        if r["dtype"] == "float32":
            a, b = by[("float32", r["steps"])], by[("float64", r["steps"])]
            r["rel_diff_vs_float64"] = float(np.linalg.norm(a - b) / np.linalg.norm(b))
    return rows


def plot_gradients(rows, path):
    fig, ax = subplots(1, 2, figsize=(9, 3.4))
    for dtype, style in (("float64", "o-"), ("float32", "s--")):
        rs = [r for r in rows if r["dtype"] == dtype]
        ax[0].semilogy([r["horizon_s"] for r in rs], [r["grad_norm"] for r in rs], style, label=dtype)
    rs = [r for r in rows if r["dtype"] == "float32"]
    ax[1].semilogy([r["horizon_s"] for r in rs], [max(r["rel_diff_vs_float64"], 1e-17) for r in rs], "s-")
    ax[0].set(xlabel="horizon [s] (dt = 0.01, RK4)", ylabel="||d loss / d controls||",
              title="acrobot: gradient norm vs horizon")
    ax[1].set(xlabel="horizon [s]", ylabel="relative difference", title="float32 gradient vs float64")
    ax[0].legend()
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    save_figure(fig, path, dpi=90)


# part 5: the hopper and the half-cheetah dropped on the ground
DROP_MU = {"hopper": 0.9, "half_cheetah": 1.0}  # Gymnasium's models and the friction coefficient of each
DROP_KE = (2e3, 2e4, 2e5)
DROP_STEPS = tuple(0.1 * 2 ** (-k / 2) for k in range(17))  # the fixed steps tried, 0.1 s to 2.5e-4 s, largest first
DROP_S, DROP_HEIGHT, DROP_TILTS = 2.0, 0.5, (-0.2, 0.0, 0.2)  # seconds, m above qpos0, rad (rooty)
DROP_ENERGY_STEPS, DROP_TOLERANCES = (5e-3, 5e-4), (1e-4, 1e-6)


def _bounded(e, scale):
    """Whether the energies ``e`` (steps, states) stay finite and never more than ``scale`` above their start."""
    e = np.asarray(e)
    return bool(np.all(np.isfinite(e)) and np.max(e - e[0]) <= scale)


def dropped(name, ke, damped=True):
    """Gymnasium's ``name`` with penalty contact of stiffness ``ke`` and penalty limits (``PenaltyLimits(1e3, 10)``),
    and its drop states (:data:`DROP_TILTS`, ``DROP_HEIGHT`` above ``qpos0``, at rest). ``damped=False``: no contact
    damping or friction (``kd = kf = 0``), no limit damping and no joint damping: a conservative model."""
    k = 1e3 if damped else 0.0
    chain = from_mjcf(gymnasium_model(name), contact=lg.PenaltyContact(ke, k, k, DROP_MU[name]),
                      limits=lg.PenaltyLimits(1e3, 10.0 if damped else 0.0))
    if not damped:
        joints = lambda c: [j.damping for b in c.bodies for j in b.joints]  # noqa: E731
        chain = eqx.tree_at(joints, chain, [np.zeros_like(d) for d in joints(chain)])
    q0 = np.zeros((len(DROP_TILTS), chain.nq))
    q0[:, 1] = (1.25 if name == "hopper" else 0.0) + DROP_HEIGHT  # rootz's qpos0: 1.25 (hopper) and 0 (cheetah)
    q0[:, 2] = DROP_TILTS
    return chain, jnp.asarray(q0)


@eqx.filter_jit
def _drop(chain, q0, h, steps):
    """Semi-implicit Euler drops from the states ``q0`` (at rest, unactuated): the total energy (the penalty springs'
    included) and rootz at every step, shape ``(steps + 1, states)``."""
    tr = jax.vmap(lambda q: _rollout(chain, q, jnp.zeros_like(q), h, lg.SemiImplicitEuler(), steps))(q0)
    kin, pot = lg.energy(chain, tr.q, tr.qd)
    return (kin + pot).T, tr.q[..., 1].T


def step_estimate(chain, q):
    """``(2 sqrt(m_eff / ke), m_eff)``: ``m_eff = 1 / (J M^-1 J^T)`` the lightest of the contact points' effective
    masses along the ground's normal at ``q`` (``J``: the gradient of a point's height)."""
    J = np.asarray(jax.jacfwd(lambda q: contact_point_positions(chain, q)[:, 2])(q))  # the points' heights
    m_eff = 1 / np.max(np.sum(J * np.linalg.solve(np.asarray(lg.mass_matrix(chain, q)), J.T).T, axis=1))
    return 2 * np.sqrt(m_eff / float(chain.contact.ke)), m_eff


def _timed(fn, *args):
    """``(outputs as NumPy arrays, the least seconds of 3 calls after the first)``: the first call compiles."""
    out = jax.block_until_ready(fn(*args))
    return [np.asarray(x) for x in out], median_time(fn, *args, repeats=3, min_time=0.0, warmup=0, best=True)


def contact_drops(quick):
    """For the hopper and the half-cheetah dropped on the ground: the largest stable fixed step against ``ke`` (stable:
    finite, the total energy never more than ``M g 1 m`` above its start over ``DROP_S``; every state of
    :func:`dropped`) beside :func:`step_estimate`; at ``ke = 2e4``, from the first state, the energy's largest error
    and largest rise above its running minimum (both in units of ``M g 1 m``) at ``DROP_ENERGY_STEPS``, and Tsit5
    with error control (``rtol = atol``, restarted at every 10 ms interval) through the impacts: its steps, wall
    time (compile excluded) and energy error beside the fixed steps'."""
    out = dict(horizon_s=DROP_S, drop_height_m=DROP_HEIGHT, tilts=DROP_TILTS, stable=[], energy=[], adaptive=[])
    for name in DROP_MU:
        for ke in DROP_KE[1:2] if quick else DROP_KE:
            for damped in (True, False):
                chain, q0 = dropped(name, ke, damped)
                h_est, m_eff = step_estimate(chain, q0[0])
                scale = float(jnp.sum(chain.mass)) * 9.81
                largest = next((h for h in DROP_STEPS if _bounded(_drop(chain, q0, h, round(DROP_S / h))[0], scale)),
                               None)
                out["stable"].append(dict(model=name, ke=ke, damped=damped, largest_stable_step=largest,
                                          estimate_2_sqrt_m_eff_over_ke=h_est, m_eff=m_eff))
                print(f"  drop {out['stable'][-1]}", flush=True)
    adaptive = eqx.filter_jit(_adaptive_rollout)
    for name in DROP_MU:
        for damped in (True, False):
            chain, q0 = dropped(name, 2e4, damped)
            scale = float(jnp.sum(chain.mass)) * 9.81
            row = dict(model=name, ke=2e4, damped=damped)
            for h in DROP_ENERGY_STEPS:
                (e, z), wall = _timed(_drop, chain, q0[:1], h, round(DROP_S / h))
                out["energy"].append(row | dict(step=h, steps=round(DROP_S / h), wall_s=wall, trace=(e[:, 0], z[:, 0]),
                                                max_energy_change=float(np.max(np.abs(e - e[0])) / scale),
                                                max_rise=float(np.max(e - np.minimum.accumulate(e)) / scale)))
            for tol in DROP_TOLERANCES:
                (q, qd, accepted, rejected, _, _, failed), wall = _timed(
                    adaptive, chain, q0[0], jnp.zeros_like(q0[0]), 0.01, round(DROP_S / 0.01), jnp.asarray(tol),
                    jnp.asarray(tol), 4096)
                e = np.sum(lg.energy(chain, q, qd), axis=0)
                out["adaptive"].append(row | dict(rtol_atol=tol, failed=bool(failed), steps=int(accepted + rejected),
                                                  rejected=int(rejected), wall_s=wall,
                                                  max_energy_change=float(np.max(np.abs(e - e[0])) / scale)))
    return out


def plot_drop(rows, path):
    """Rootz and the total energy against time of the hopper's damped drop at the two steps of ``rows``."""
    fig, ax = subplots(1, 2, figsize=(10, 3.6))
    for r in rows:
        t = np.arange(r["steps"] + 1) * r["step"]
        for a, y in zip(ax, r["trace"][::-1]):
            a.plot(t, y, lw=0.9, label=f"h = {r['step']:g} s")
    ax[0].set(xlabel="time [s]", ylabel="rootz [m]", title="hopper dropped (ke 2e4, kd = kf = 1e3, mu 0.9)")
    ax[1].set(xlabel="time [s]", ylabel="total energy [J]", title="energy, penalty springs included")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend()
    save_figure(fig, path, dpi=90)


# the stress batch: its chain sizes and states in all (split evenly among them), by --quick
STRESS = {False: ((2, 3, 5, 8, 12, 20), 10_000), True: ((2, 3, 5, 8), 1000)}
# the error-controlled mode's states per chain size, by --quick: fewer where the adaptive solve costs more
# (about 0.01, 0.07, 0.6, 1 and 3 s a trajectory at n = 3, 5, 8, 12, 20 on 2 shared cores: 3 minutes in all)
ADAPTIVE_STATES = {False: {3: 400, 5: 200, 8: 50, 12: 30, 20: 20}, True: {3: 50, 5: 25, 8: 10}}


def _fixed_step_sweeps(out, quick, path, plot_path):
    """Parts 1-4 into ``out``, written to ``path`` as they finish."""
    steps = 20_000 if quick else 100_000
    print(f"energy drift over {steps} steps", flush=True)
    out["energy_drift"] = energy_drift(steps)
    print(markdown_table(out["energy_drift"], ["system", "solver", "dt", "first_half", "second_half", "max"]))

    print("float32 vs float64 parting times", flush=True)
    out["parting"] = parting(steps=10_000 if quick else 30_000)

    horizons = [10, 30, 100, 300, 1000] if quick else [10, 20, 50, 100, 200, 500, 1000, 2000, 5000]
    print("gradient norm vs horizon (acrobot)", flush=True)
    out["gradient_growth"] = gradient_growth(horizons)
    print(markdown_table(out["gradient_growth"], ["dtype", "horizon_s", "grad_norm", "rel_diff_vs_float64"]))
    plot_gradients(out["gradient_growth"], plot_path)
    write_json(path, out)

    # the stress batch last: compiling 12- and 20-link chains is the slow part
    sizes, total = STRESS[quick]
    print(f"stress: {total} random states, n in {sizes}", flush=True)
    out["stress"] = []
    for n in sizes:
        out["stress"].append(stress(n, total // len(sizes)))
        write_json(path, out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced sweep")
    ap.add_argument("--adaptive-only", action="store_true",
                    help="only the error-controlled stress sweep (2b): replaces its key in the JSON, keeps the rest")
    ap.add_argument("--contact-only", action="store_true",
                    help="only the drops on the ground (5): replaces their key in the JSON, keeps the rest")
    args = ap.parse_args(argv)
    results, img = outputs(args.quick)
    suffix = "_quick" if args.quick else ""
    path, plot_path = results / f"stability{suffix}.json", img / f"stability_gradients{suffix}.png"
    t0 = time.perf_counter()
    out = {"quick": args.quick, "device": str(jax.devices()[0]), "float": "float64 unless stated"}
    if args.adaptive_only or args.contact_only:
        out = json.loads(path.read_text()) if path.exists() else out
    else:
        _fixed_step_sweeps(out, args.quick, path, plot_path)
    if not args.adaptive_only:
        print("contact: the hopper and the half-cheetah dropped on the ground", flush=True)
        out["contact"] = drops = contact_drops(args.quick)
        drop_plot = img / f"hopper_drop{suffix}.png"
        plot_drop([r for r in drops["energy"] if r["model"] == "hopper" and r["damped"]], drop_plot)
        for r in drops["energy"]:
            r.pop("trace")
        for key in ("stable", "energy", "adaptive"):
            print(markdown_table(drops[key], list(drops[key][0])))
        write_json(path, out)
        if args.contact_only:
            return print(f"wrote {path} and {drop_plot} ({time.perf_counter() - t0:.0f} s)")

    sizes, total = STRESS[args.quick]
    states = ADAPTIVE_STATES[args.quick]
    print(f"adaptive stress: Tsit5 with error control on {sum(states.values())} of the stress states, "
          f"{states} per chain size", flush=True)
    t = time.perf_counter()
    out["adaptive_stress"] = adaptive_stress(states, total // len(sizes))
    out["adaptive_stress"]["wall_s"] = time.perf_counter() - t
    if not args.adaptive_only:
        out["total_wall_s"] = time.perf_counter() - t0
    write_json(path, out)
    written = path if args.adaptive_only else f"{path} and {plot_path}"
    print(f"wrote {written} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
