"""A humanoid tumbling in free flight: dm_control's 27-dof humanoid read from MJCF as a spatial tree, thrown spinning
without gravity, damping or springs, its energy and momentum over time.

    python examples/humanoid_free_flight.py [--seconds 2] [--out runs/humanoid_free_flight]   # pip install -e ".[test]"

Writes ``free_flight.png``: the body's poses along the flight (seen from the side) and the relative errors of the
energy, the linear momentum and the angular momentum about the world's origin (RK4 and semi-implicit Euler, 5 ms
steps). Without external forces the exact flow conserves all three; a solver's errors in them fall at its order
(RK4: fourth, semi-implicit Euler: first).
"""

import argparse
import pathlib

import dm_control
import jax
import jax.numpy as jnp
import matplotlib
import mujoco
import numpy as np

import lagrange as lg
from lagrange.interop.mjcf import from_mjcf

jax.config.update("jax_enable_x64", True)
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MODEL = pathlib.Path(dm_control.__file__).parent / "suite" / "humanoid.xml"


def momenta(tree, q, qd):
    """Linear momentum and angular momentum about the world's origin: the free joint's conjugate momenta (``M qd``'s
    first six entries: world-frame force, body-frame moment about the root), moved to the world's origin."""
    p = jnp.einsum("...ij,...j->...i", lg.mass_matrix(tree, q), qd)
    w, x, y, z = (q[..., 3 + i] for i in range(4))
    R = jnp.stack([jnp.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                   jnp.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
                   jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1)], -2)
    return p[..., :3], jnp.cross(q[..., :3], p[..., :3]) + jnp.einsum("...ij,...j->...i", R, p[..., 3:6])


def main(seconds, out):
    model = mujoco.MjModel.from_xml_path(str(MODEL))
    model.opt.gravity[:], model.dof_damping[:], model.jnt_stiffness[:] = 0.0, 0.0, 0.0
    tree = from_mjcf(model, limits="ignore", contact="ignore")  # a lagrange.model.tree.Tree: q = qpos, qd = qvel
    rng = np.random.default_rng(0)
    q0 = jnp.asarray(model.qpos0 + np.r_[np.zeros(7), rng.uniform(-0.5, 0.5, model.nq - 7)])
    qd0 = jnp.asarray(np.r_[0.5, 0.0, 1.0, 2.0, -1.0, 3.0, rng.uniform(-2, 2, model.nv - 6)])
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for solver, style in ((lg.SemiImplicitEuler(), "--"), (lg.RK4(), "-")):
        steps = int(round(seconds / 0.005))
        tr = jax.jit(lambda q, qd: lg.simulate(tree, q, qd, jnp.zeros((steps, tree.m)), 0.005, solver))(q0, qd0)
        energy = sum(lg.energy(tree, tr.q, tr.qd))
        P, L = momenta(tree, tr.q, tr.qd)
        name = type(solver).__name__
        for ax, x, what in zip(axes[1:], (energy, P, L), ("energy", "linear momentum", "angular momentum")):
            err = jnp.linalg.norm(jnp.atleast_2d((x - x[0]).T).T, axis=-1) / jnp.linalg.norm(jnp.atleast_1d(x[0]))
            ax.semilogy(tr.t[1:], np.maximum(np.asarray(err[1:]), 1e-17), style, label=name)
            ax.set(title=f"relative error of the {what}", xlabel="t [s]")
        print(f"{name}: energy error {float(jnp.max(jnp.abs(energy - energy[0])) / energy[0]):.1e}, momenta "
              f"{float(jnp.max(jnp.abs(P - P[0]))):.1e} / {float(jnp.max(jnp.abs(L - L[0]))):.1e}")
    for k in range(0, steps + 1, steps // 8):  # RK4's poses (the last run): every body's origin, in the x-z plane
        x = np.asarray(lg.positions(tree, tr.q[k]))
        axes[0].plot(x[:, 0], x[:, 2], "o", ms=3, alpha=0.4 + 0.6 * k / steps)
    axes[0].set(title="body origins along the flight (x-z)", xlabel="x [m]", ylabel="z [m]", aspect="equal")
    axes[1].legend()
    out.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out / "free_flight.png", dpi=90)
    print(f"wrote {out / 'free_flight.png'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("runs/humanoid_free_flight"))
    main(**vars(parser.parse_args()))
