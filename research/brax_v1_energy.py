"""Does the authors' simulator, Brax v1 with its spring joints, conserve the double cartpole's energy as the exact
chain does? A whirling pole that loses energy in Brax v1 costs a policy effort there that it does not cost here.

    /tmp/bv1/bin/python research/brax_v1_energy.py      # in a virtual environment of its own, see below

Brax v1 is not this project's dependency and does not run on its JAX: make a separate environment,
``python3 -m venv /tmp/bv1 && /tmp/bv1/bin/pip install brax==0.9.4 jax==0.4.23 jaxlib==0.4.23 flax==0.7.5
optax==0.1.7 chex==0.1.85 orbax-checkpoint==0.4.8 "numpy<2" "scipy<1.13" mujoco==3.1.1 mujoco-mjx==3.1.1``. The
script imports nothing from this repository.

The system is the double cartpole on the Brax v1 bodies as ``lagrange.systems.BRAX_V1["double_cartpole"]`` records
them, written as a Brax v1 config by this script: a 10.47 kg cart sliding in x, two 5.02 kg capsule poles hinged
0.3 m either side of their centres, inertias left to Brax v1's default (1 kg m^2), joints of stiffness 30000 and
spring damping 500, a 1000 N thruster, dt 0.01 s in 12 substeps: the values of the authors' fork's
``inverted_double_pendulum_swingup``. With zero force, released at rest from a few poses (swinging, and falling from
near upright into a fast swing), it integrates 500 control steps (5 s) and reports the mechanical energy (kinetic,
translational and rotational, plus potential) against its start, as a fraction of the energy the motion has above
hanging still, and the turns the first pole makes.
The exact chain conserves energy to RK4's error (``tests/lagrange/test_stability.py``: relative 1e-6 over such runs in
float64). Writes ``research/results/brax_v1_energy.json``.
"""

from __future__ import annotations

import json
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np
from brax.v1.physics import config_pb2
from brax.v1.physics.system import System
from google.protobuf import text_format

POLE_MASS, CART_MASS, G = 5.0185914, 10.471975, 9.81

CONFIG = """
bodies { name: "cart" mass: %(cart)r
  colliders { rotation { x: 90 z: 90 } capsule { radius: 0.1 length: 0.4 } }
  frozen { position { x: 0 y: 1 z: 1 } rotation { x: 1 y: 1 z: 1 } } }
bodies { name: "pole" mass: %(pole)r
  colliders { capsule { radius: 0.049 length: 0.69800085 } }
  frozen { position { x: 0 y: 1 z: 0 } rotation { x: 1 y: 0 z: 1 } } }
bodies { name: "pole2" mass: %(pole)r
  colliders { capsule { radius: 0.049 length: 0.69800085 } }
  frozen { position { x: 0 y: 1 z: 0 } rotation { x: 1 y: 0 z: 1 } } }
joints { name: "hinge" stiffness: 30000.0 parent: "cart" child: "pole" child_offset { z: -0.3 }
  rotation { z: 90.0 } limit_strength: 0.0 spring_damping: 500.0 angle_limit { min: -360.0 max: 360.0 } }
joints { name: "hinge2" stiffness: 30000.0 parent: "pole" child: "pole2" parent_offset { z: 0.3 } \
child_offset { z: -0.3 }
  rotation { z: 90.0 } limit_strength: 0.0 spring_damping: 500.0 angle_limit { min: -360.0 max: 360.0 } }
forces { name: "cart_thruster" body: "cart" strength: 1000.0 thruster {} }
collide_include {}
gravity { z: -9.81 }
defaults { angles { name: "hinge" angle { x: 180.0 y: 0.0 z: 0.0 } } }
dt: 0.01
substeps: 12
""" % {"cart": CART_MASS, "pole": POLE_MASS}  # noqa: UP031

# (name, joint angles offset from hanging [rad]): released at rest, so Brax v1's bodies start exactly on its joints
STARTS = [
    ("released at 0.5 rad", (0.5, 0.0)),
    ("released at 1.5 rad", (1.5, 0.0)),
    ("released at 2.5 rad, bent -1 rad", (2.5, -1.0)),
    ("released at 3.1 rad (near upright)", (3.1, 0.0)),
    ("released at 3.1 rad, bent 0.5 rad", (3.1, 0.5)),
]


def energy(sys, qp):
    """Kinetic (translational + rotational, Brax v1's body inertias in the body frame) plus potential energy."""
    mass = sys.body.mass
    ke = 0.5 * jnp.sum(mass * jnp.sum(qp.vel**2, axis=-1))

    def rot_ke(q, w, inertia):
        # world angular velocity into the body frame: rotate by the conjugate quaternion
        w_body = rotate(w, q * jnp.array([1.0, -1.0, -1.0, -1.0]))
        return 0.5 * jnp.sum(inertia * w_body**2)  # Brax v1 keeps each body's diagonal inertia

    ke_rot = jnp.sum(jax.vmap(rot_ke)(qp.rot, qp.ang, sys.body.inertia))
    pe = jnp.sum(mass * G * qp.pos[:, 2])
    return ke + ke_rot + pe


def rotate(v, q):
    """Rotate the vector ``v`` by the unit quaternion ``q = (w, x, y, z)``."""
    w, u = q[0], q[1:]
    return v + 2.0 * jnp.cross(u, jnp.cross(u, v) + w * v)


def main():
    config = text_format.Parse(CONFIG, config_pb2.Config())
    sys_ = System(config)
    step = jax.jit(lambda qp: sys_.step(qp, jnp.zeros(1))[0])
    angles = jax.jit(lambda qp: sys_.joints[0].angle_vel(qp))
    rows = []
    for name, dq in STARTS:
        qp = sys_.default_qp(joint_angle=sys_.default_angle() + jnp.array(dq))
        e0 = float(energy(sys_, qp))
        # hanging still with the cart at this start's height (default_qp lifts the system clear of the ground, by an
        # amount that depends on the pose): the energy a motion has above rest is e0 minus this
        z = float(qp.pos[0, 2])
        rest = G * POLE_MASS * ((z - 0.3) + (z - 0.9)) + G * CART_MASS * z
        es, turns = [e0], 0.0
        a0, _ = angles(qp)
        prev = np.asarray(a0)
        for _ in range(500):
            qp = step(qp)
            es.append(float(energy(sys_, qp)))
            a, _ = angles(qp)
            a = np.asarray(a)
            turns += abs(float(np.angle(np.exp(1j * (a[0] - prev[0]))))) / (2 * np.pi)
            prev = a
        es = np.array(es)
        above = e0 - rest
        row = {"start": name, "energy_start_J": e0, "energy_above_rest_J": above,
               "energy_after_1s_J": float(es[100]), "energy_after_5s_J": float(es[-1]),
               "relative_loss_after_5s": float((e0 - es[-1]) / max(above, 1e-9)),
               "max_relative_excursion": float(np.max(np.abs(es - e0)) / max(above, 1e-9)),
               "first_pole_turns": turns}
        rows.append(row)
        print(json.dumps(row), flush=True)
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "brax_v1_energy.json")
    with open(out, "w") as f:
        json.dump({"brax": "0.9.4 (brax.v1)", "jax": jax.__version__, "rows": rows}, f, indent=1)
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(main())
