"""A quadruped read from URDF with a floating base, dropped on the ground, standing under PD position actuators.

``from_urdf`` reads the robot as it ships (``floating_base=True``), a sphere given by hand on each foot (their
collision geometry is a mesh) presses the ground and each joint gets MuJoCo's ``<position kp kv>``, its target the
standing pose. Dropped 5 cm in that pose, it has stood if its trunk ends above half its start height, tilted < 0.3
rad. The robot: ODRI's Solo12 (``examples/assets/solo12.urdf``, 12 dof, 2.5 kg), or another (``--urdf``: docs/urdf.md
stands Go1). ``python examples/quadruped_stand.py [--seconds 2] [--out runs/quadruped_stand] [--quick]``
"""

import argparse
import pathlib

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import lagrange as lg
from lagrange.interop.urdf import from_urdf
from lagrange.kinematics import contact_point_positions
from optim.checkpoint import write_json

DT, SUBSTEPS = 0.01, 10  # targets at 100 Hz, semi-implicit Euler at 1 kHz


def main(args):
    jax.config.update("jax_enable_x64", True)
    tree = from_urdf(args.urdf, floating_base=True, motors=lambda k: lg.AffineActuator.position(k, args.kp, args.kv),
                     contact=lg.PenaltyContact(args.ke, args.ke / 100, args.ke / 20, 0.9),
                     contact_points={foot: [(0.0, 0.0, 0.0, args.foot_radius)] for foot in args.feet})
    q0 = np.array(tree.neutral(), float)
    q0[7:] = np.tile(args.pose, (tree.nq - 7) // len(args.pose))  # leg by leg, hip to foot
    q0[2] += 0.05 + min(p[3] for b in tree.bodies for p in b.contacts) - np.min(
        np.asarray(contact_point_positions(tree, jnp.asarray(q0)))[:, 2])  # the feet 5 cm above the ground
    targets = jnp.broadcast_to(jnp.asarray(q0[7:]), (round(args.seconds / DT), tree.m))
    traj = jax.jit(lambda q0: lg.simulate(tree, q0, jnp.zeros(tree.nv), targets, DT, lg.SemiImplicitEuler(),
                                          SUBSTEPS))(jnp.asarray(q0))
    q, t = np.asarray(traj.q), np.asarray(traj.t)
    tilt = np.arccos(np.clip(1 - 2 * (q[:, 4] ** 2 + q[:, 5] ** 2), -1, 1))  # the trunk's z against the world's
    stood = bool(q[-1, 2] > q0[2] / 2 and tilt[-1] < 0.3)
    (out := pathlib.Path(args.out)).mkdir(parents=True, exist_ok=True)
    write_json(out / "results.json", dict(stood=stood, seconds=args.seconds, start_height=float(q0[2]),
                                          final_height=float(q[-1, 2]), min_height=float(q[:, 2].min()),
                                          final_tilt=float(tilt[-1]), urdf=str(args.urdf), nq=tree.nq, nv=tree.nv))
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(7, 8), gridspec_kw=dict(height_ratios=[1, 1, 1.2]))
    a.plot(t, q[:, 2])
    a.set(ylabel="trunk height [m]", title=f"{args.urdf.stem}: {'stands' if stood else 'falls'}")
    for k, j in enumerate(tree.joints[1:], start=1):
        b.plot(t, q[:, tree.qadr[k]], lw=0.8, label=j.name)
    b.set(ylabel="joint angle [rad]", xlabel="time [s]")
    b.legend(fontsize=6, ncol=4)
    for x, color in ((q[0], "0.6"), (q[-1], "C0")):  # each body from its parent's origin, each foot from its body's
        p, feet = (np.asarray(f(tree, jnp.asarray(x))) for f in (lg.positions, contact_point_positions))
        ends = [(p[j], p[i]) for i, j in enumerate(tree.parents) if j >= 0]
        for a0, a1 in ends + list(zip(p[[i for i, b in enumerate(tree.bodies) for _ in b.contacts]], feet)):
            c.plot([a0[0], a1[0]], [a0[2], a1[2]], "o-", color=color, ms=3)
    c.axhline(0.0, color="k", lw=0.8)
    c.set(aspect="equal", title="side view: start (grey), end (blue)", xlabel="x [m]", ylabel="z [m]")
    fig.tight_layout()
    fig.savefig(out / "stand.png", dpi=120)
    print(f"{'stood' if stood else 'fell'}: trunk {q0[2]:.3f} -> {q[-1, 2]:.3f} m (lowest {q[:, 2].min():.3f}), tilt "
          f"{tilt[-1]:.3f} rad after {args.seconds} s; {out}/results.json, stand.png")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urdf", type=pathlib.Path, default=pathlib.Path(__file__).parent / "assets/solo12.urdf")
    parser.add_argument("--feet", nargs="+", default=["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"], help="foot links")
    parser.add_argument("--foot-radius", type=float, default=0.016, help="each foot's sphere [m], at its origin")
    parser.add_argument("--pose", type=float, nargs="+", default=[0, 0.8, -1.6] * 2 + [0, -0.8, 1.6] * 2,
                        help="the joints' standing angles [rad]: all of them, or one leg's, repeated")
    parser.add_argument("--kp", type=float, default=5.0, help="the servos' stiffness [N m/rad]")
    parser.add_argument("--kv", type=float, default=0.1, help="the servos' damping [N m s/rad]")
    parser.add_argument("--ke", type=float, default=5e3, help="the ground's stiffness [N/m] (damping ke/100 N s/m)")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--out", default="runs/quadruped_stand")
    parser.add_argument("--quick", action="store_true", help="0.5 s instead of --seconds")
    args = parser.parse_args()
    args.seconds = 0.5 if args.quick else args.seconds
    main(args)
