"""Train SHAC on the SHAC paper's Hopper (DFlex's, exact dynamics with penalty contact) with the authors' settings.

    python examples/hopper_shac.py            # the authors' 2000 epochs x 256 envs x 32 steps (16.4M env steps)
    python examples/hopper_shac.py --quick    # a short demo: a gait that moves forward in a few minutes
    python examples/hopper_shac.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (the deterministic policy's mean return over 16 episodes, env steps,
wall-clock), ``learning_curve.png`` (against env steps and against wall-clock), ``gait.png`` and ``gait.gif`` to
``--out``. The published anchor (the AHAC paper's data for SHAC on DFlex's hopper, 1000-step episodes) is ~4800.
"""

from lagrange.tasks import Hopper
from optim import SHACConfig
from optim.locomotion_cli import locomotion_main

CONFIG = SHACConfig.hopper()  # the authors' hopper.yaml
QUICK = SHACConfig.hopper(num_envs=64, iterations=300)

if __name__ == "__main__":
    locomotion_main(__doc__.splitlines()[0], "runs/hopper_shac", Hopper.diffrl, CONFIG, QUICK, anchor=4800.0)
