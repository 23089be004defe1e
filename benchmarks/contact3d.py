"""3-D trees dropped on the ground: the largest stable step of semi-implicit Euler against the contact stiffness.

    python -m benchmarks.contact3d          # Gymnasium's ant and humanoid, about 5 minutes on 2 cores

Gymnasium's ant (``PenaltyLimits(1e3, 10)`` on its limited hinges) and humanoid (``limits="ignore"``: its limited
tendons have no penalty form) with ``PenaltyContact(ke, kd, kf, 0.9)``, dropped unactuated from 0.5 m above
``qpos0`` (limited joints clipped into their ranges) at three tilts of the root, for 1.5 s. "Stable": every state
finite and the energy (penalty springs included) never more than ``M g * 1 m`` above its start; steps on a grid of
ratio sqrt(2) from 40 ms down, the largest stable one reported. "Damped": ``kd = kf = 1e3``; "conservative": ``kd =
kf = 0``, the joints' damping as written. The estimate ``2 sqrt(m_eff / ke)`` uses the lightest contact point's
effective mass ``1 / (J M^-1 J^T)`` (``J`` its vertical velocity's Jacobian) at the first tilt's landing pose.
Float64. Writes ``benchmarks/results/contact3d.{json,md}`` and ``docs/img/ant_drop.png`` (the ant's height and
energy at two steps; ``--figure-only``: the figure alone).

    python -m benchmarks.contact3d --adaptive   # adaptive steps through the impacts, about 3 minutes

Each model (damped law, ke 2e4) dropped from the second tilt, one environment: diffrax's adaptive Tsit5 at three
tolerances and semi-implicit Euler at three steps, against Dopri8 at ``rtol = atol = 1e-10`` (control intervals of
10 ms, the adaptive steps inside each): the largest error of the final ``q`` and the run time of the compiled program
(the best of 5 calls), side by side in one process. Writes ``benchmarks/results/contact3d_adaptive.{json,md}``.
"""

from __future__ import annotations

import argparse

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import lagrange as lg  # noqa: E402
from benchmarks._cli import REPO, gymnasium_model, markdown_table  # noqa: E402
from benchmarks._timing import median_time  # noqa: E402
from lagrange.interop.mjcf import from_mjcf  # noqa: E402
from lagrange.rbda.contact import contact_spots  # noqa: E402
from lagrange.rbda.kinematics import Kinematics  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402

KES = (2e3, 2e4, 2e5)
TILTS = (0.0, 0.3, 0.6)  # rad about the x axis
DURATION, HEIGHT, MU = 1.5, 0.5, 0.9
H_GRID = tuple(0.04 / np.sqrt(2) ** k for k in range(16))  # 40 ms ... 0.2 ms


def dropped(name, ke, damped):
    k = 1e3 if damped else 0.0
    limits = lg.PenaltyLimits(1e3, 10.0) if name == "ant" else "ignore"
    tree = from_mjcf(gymnasium_model(name), contact=lg.PenaltyContact(ke, k, k, MU), limits=limits)
    q0 = np.array(tree.neutral(), float)
    for j, a in zip(tree.joints, tree.qadr):  # into the ranges (the ant's ankles are out of theirs at qpos0)
        if j.range is not None:
            q0[a] = np.clip(q0[a], *j.range)
    starts = []
    for tilt in TILTS:
        q = q0.copy()
        q[2] += HEIGHT
        q[3:7] = [np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0]
        starts.append(q)
    return tree, jnp.asarray(np.stack(starts))


def _total_mass(tree):
    return float(sum(float(b.mass) for b in tree.bodies))


def drop_fn(tree):
    """``(h, q0) -> (finite, max energy rise, final height)`` of a ``DURATION`` drop at step ``h`` (traced)."""
    solver = lg.SemiImplicitEuler()

    def one(h, q0):
        qd0 = jnp.zeros(tree.nv)
        e0 = sum(lg.energy(tree, q0, qd0))
        n = jnp.ceil(DURATION / h).astype(int)

        def body(carry):
            i, q, qd, worst, ok = carry
            q, qd = lg.step(tree, q, qd, jnp.zeros(tree.m), h, solver)
            e = sum(lg.energy(tree, q, qd))
            ok = ok & jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(qd))
            return i + 1, q, qd, jnp.maximum(worst, jnp.where(jnp.isfinite(e), e - e0, jnp.inf)), ok

        def cond(carry):
            return (carry[0] < n) & carry[4] & (carry[3] < 1e6)

        _, q, _, worst, ok = jax.lax.while_loop(cond, body, (0, q0, qd0, -jnp.inf, True))
        return ok, worst, q[2]

    return jax.jit(jax.vmap(one, in_axes=(None, 0)))


def largest_stable(tree, starts):
    run = drop_fn(tree)
    bound = _total_mass(tree) * 9.81 * 1.0
    for h in H_GRID:
        ok, worst, _ = run(jnp.asarray(h), starts)
        if bool(jnp.all(ok)) and float(jnp.max(worst)) <= bound:
            return h
    return None


def step_estimate(tree, q):
    """``(2 sqrt(m_eff / ke), m_eff)`` for the lightest contact point at ``q``."""
    def spot_vz(qd):
        k = Kinematics(tree, q, qd)
        links, s, _ = contact_spots(k)
        v = k.v[..., links, :]
        return (v[..., 3:] + jnp.cross(v[..., :3], s))[..., 2]

    J = np.asarray(jax.jacfwd(spot_vz)(jnp.zeros(tree.nv)))
    Minv = np.linalg.inv(np.asarray(lg.mass_matrix(tree, q)))
    m_eff = float(np.min(1.0 / np.einsum("ki,ij,kj->k", J, Minv, J)))
    return 2 * np.sqrt(m_eff / float(tree.contact.ke)), m_eff


def drop_figure(path, ke=2e4, steps=(2.5e-3, 5e-4)):
    """The ant (damped law, ``ke``) dropped from the first tilt: the root's height and the energy (penalty springs
    included) over ``DURATION`` at two steps, one panel each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tree, starts = dropped("ant", ke, damped=True)
    q0 = starts[1]
    fig, (ax_h, ax_e) = plt.subplots(1, 2, figsize=(9, 3.2))
    for h in steps:
        n = int(round(DURATION / h))
        tr = lg.simulate(tree, q0, jnp.zeros(tree.nv), jnp.zeros((n, tree.m)), h, lg.SemiImplicitEuler())
        kin, pot = jax.vmap(lambda q, qd: lg.energy(tree, q, qd))(tr.q, tr.qd)
        t = np.arange(n + 1) * h
        ax_h.plot(t, np.asarray(tr.q[:, 2]), label=f"h = {h * 1e3:g} ms")
        ax_e.plot(t, np.asarray(kin + pot), label=f"h = {h * 1e3:g} ms")
    ax_h.set(xlabel="t [s]", ylabel="torso height [m]", title="Gymnasium's ant dropped 0.5 m, tilted 0.3 rad")
    ax_e.set(xlabel="t [s]", ylabel="energy [J]", title=f"energy, penalty springs included (ke {ke:.0e})")
    ax_h.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


TOLERANCES = (1e-4, 1e-6, 1e-8)
EULER_STEPS = (2.5e-3, 5e-4, 1e-4)
INTERVAL = 0.01


def _timed_drop(tree, q0, solver, substeps, tol=None):
    """The final ``q`` of a ``DURATION`` drop from ``q0`` and the run time [s] of its compiled program (the best of 5
    repeats after the first call)."""
    n = int(round(DURATION / INTERVAL))
    run = jax.jit(lambda q: lg.simulate(tree, q, jnp.zeros(tree.nv), jnp.zeros((n, tree.m)), INTERVAL, solver,
                                        substeps=substeps, rtol=tol, atol=tol, max_steps=100_000).q[-1],
                  compiler_options=lg.compiler_options(tree))
    return np.asarray(run(q0)), median_time(run, q0, repeats=5, best=True)


def adaptive_table():
    """Adaptive Tsit5 and semi-implicit Euler through the landings, against Dopri8 at 1e-10 (see the docstring)."""
    rows = []
    for name in ("ant", "humanoid"):
        tree, starts = dropped(name, 2e4, damped=True)
        q0 = starts[1]
        ref, ref_s = _timed_drop(tree, q0, lg.Dopri8(), 8, 1e-10)
        runs = [("Tsit5", f"rtol = atol = {tol:.0e}", lg.Tsit5(), 8, tol) for tol in TOLERANCES]
        runs += [("SemiImplicitEuler", f"h = {h * 1e3:g} ms", lg.SemiImplicitEuler(), int(round(INTERVAL / h)), None)
                 for h in EULER_STEPS]
        for solver_name, setting, solver, substeps, tol in runs:
            q, seconds = _timed_drop(tree, q0, solver, substeps, tol)
            row = dict(model=name, solver=solver_name, setting=setting, error=float(np.max(np.abs(q - ref))),
                       run_s=seconds, reference_run_s=ref_s)
            print(row, flush=True)
            rows.append(row)
    out = REPO / "benchmarks" / "results"
    write_json(out / "contact3d_adaptive.json", dict(rows=rows, ke=2e4, tilt=TILTS[1], duration_s=DURATION,
                                                     interval_s=INTERVAL, reference="Dopri8, rtol = atol = 1e-10"))
    keys = ["model", "solver", "setting", "final q error", "run time [s]"]
    table = markdown_table([dict(zip(keys, (r["model"], r["solver"], r["setting"], f"{r['error']:.1e}",
                                            f"{r['run_s']:.3f}"))) for r in rows], keys)
    write_text(out / "contact3d_adaptive.md", f"`python -m benchmarks.contact3d --adaptive`\n\n{table}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figure-only", action="store_true", help="only the drop figure (docs/img/ant_drop.png)")
    ap.add_argument("--adaptive", action="store_true", help="only the adaptive-step table "
                                                            "(benchmarks/results/contact3d_adaptive.md)")
    args = ap.parse_args()
    if args.adaptive:
        adaptive_table()
        return
    drop_figure(REPO / "docs" / "img" / "ant_drop.png")
    if args.figure_only:
        return
    rows = []
    for name in ("ant", "humanoid"):
        for ke in KES:
            row = dict(model=name, ke=ke)
            for damped in (True, False):
                tree, starts = dropped(name, ke, damped)
                row["damped" if damped else "conservative"] = largest_stable(tree, starts)
            landing = np.asarray(starts[0]).copy()
            landing[2] -= HEIGHT
            row["estimate"], row["m_eff"] = step_estimate(tree, jnp.asarray(landing))
            print(row, flush=True)
            rows.append(row)
    out = REPO / "benchmarks" / "results"
    write_json(out / "contact3d.json", dict(rows=rows, tilts=TILTS, duration_s=DURATION, height_m=HEIGHT))
    fmt = lambda h: "unstable at 0.2 ms" if h is None else f"{h:.2g}"  # noqa: E731
    keys = ["model", "ke [N/m]", "largest stable step, damped [s]", "conservative [s]", "2 sqrt(m_eff/ke) [s]",
            "m_eff [kg]"]
    table = markdown_table([dict(zip(keys, (r["model"], f"{r['ke']:.0e}", fmt(r["damped"]), fmt(r["conservative"]),
                                            f"{r['estimate']:.2g}", f"{r['m_eff']:.2g}"))) for r in rows], keys)
    write_text(out / "contact3d.md", f"`python -m benchmarks.contact3d`\n\n{table}\n")


if __name__ == "__main__":
    main()
