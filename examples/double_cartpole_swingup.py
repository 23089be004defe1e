"""Swing a double cartpole up and balance it: a GRU policy (H = 32) trained by CE-APG.

    python examples/double_cartpole_swingup.py [--quick] [--seed S] [--iterations N] [--out DIR] [--resume] [--bodies B]

Writes runs/double_cartpole_swingup/{checkpoint.eqx, results.json, learning_curve.png, swingup.png, swingup.gif}.
"""

from lagrange.tasks import DoubleCartpole
from optim import CEAPGConfig
from optim.cli import swingup_main
from policies import GRUPolicy

# Paper protocol: CEAPGConfig.paper() with a GRU of width 32. The default, CEAPGConfig.laptop("double_cartpole"), is
# cut to fit two CPU cores (see its docstring).
CONFIG = CEAPGConfig.laptop("double_cartpole")
QUICK = CEAPGConfig(num_candidates=8, num_elites=3, iterations=8, apg_steps=10, episodes=2, lr_start=1e-2,
                    lr_end=1e-3, init_std=0.15)

if __name__ == "__main__":
    swingup_main(__doc__.splitlines()[0], "runs/double_cartpole_swingup", CONFIG, QUICK,
                 tasks={"rods": DoubleCartpole.rods, "brax_v1": DoubleCartpole.brax_v1},
                 policy=lambda task: GRUPolicy.for_task(task, width=32), paper_return=4295.0)
