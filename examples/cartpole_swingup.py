"""Swing a cartpole up and balance it (Table I's "Pendulum"): a GRU policy trained by CE-APG.

    python examples/cartpole_swingup.py [--quick] [--seed S] [--iterations N] [--out DIR] [--resume] [--bodies B]

Writes runs/cartpole_swingup/{checkpoint.eqx, results.json, learning_curve.png, swingup.png, swingup.gif}.
"""

from lagrange.tasks import Cartpole
from optim import CEAPGConfig
from optim.cli import swingup_main
from policies import GRUPolicy

# Paper protocol: CEAPGConfig.paper(). The default, CEAPGConfig.laptop("cartpole"), is cut to fit two CPU cores (see
# its docstring).
CONFIG = CEAPGConfig.laptop("cartpole")
QUICK = CEAPGConfig(num_candidates=8, num_elites=3, iterations=8, apg_steps=10, episodes=2, lr_start=1e-2,
                    lr_end=1e-3, init_std=0.15)

if __name__ == "__main__":
    swingup_main(__doc__.splitlines()[0], "runs/cartpole_swingup", CONFIG, QUICK,
                 tasks={"rods": Cartpole.rods, "brax_v1": Cartpole.brax_v1},
                 policy=lambda task: GRUPolicy.for_task(task, width=16), paper_return=-355.0)
