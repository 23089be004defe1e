"""Define a new chain with lagrange.chain and train a policy to swing it up.

A three-link arm: a heavy upper link, a light middle link and a short forearm; the first two joints
are motorised (the wrist is passive). Observations, reward and balance criterion are the acrobot's
(``lagrange.tasks.ChainSwingup``).

    python examples/custom_chain.py [--quick] [--seed S] [--iterations N] [--out DIR] [--resume]

Writes runs/custom_chain/{checkpoint.eqx, results.json, learning_curve.png, swingup.png, swingup.gif}.
"""

from lagrange.chain import Chain, Link
from lagrange.tasks import ChainSwingup
from optim import CEAPGConfig
from optim.cli import swingup_main
from policies import GRUPolicy


def make_task():
    """The chain and its swing-up task (built when the example runs, after the CPU devices are set)."""
    chain = Chain(
        [
            Link("revolute", mass=2.0, length=0.8, damping=0.05, gear=30.0),  # shoulder motor, 30 N m
            Link("revolute", mass=1.0, length=0.6, damping=0.05, gear=15.0),  # elbow motor, 15 N m
            Link("revolute", mass=0.5, length=0.4, damping=0.05),  # passive wrist
        ],
        gravity=9.81,
    )
    # one RK4 step per 0.02 s interval: within 5e-5 of Dopri8 along the trained policy's episodes (|qd| <= 6.4 rad/s);
    # far less accurate past 20 rad/s, where some random candidates go non-finite and are dropped
    return ChainSwingup(chain, dt=0.02, horizon=250)


CONFIG = CEAPGConfig(num_candidates=24, num_elites=8, iterations=40, apg_steps=25, episodes=2, lr_start=1e-2,
                     lr_end=1e-4, init_std=0.15)
QUICK = CEAPGConfig(num_candidates=8, num_elites=3, iterations=8, apg_steps=10, episodes=2, lr_start=1e-2,
                    lr_end=1e-3, init_std=0.15)

if __name__ == "__main__":
    swingup_main(__doc__.splitlines()[0], "runs/custom_chain", CONFIG, QUICK, tasks={"custom": make_task},
                 policy=lambda task: GRUPolicy.for_task(task, width=16))
