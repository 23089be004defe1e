"""Train SHAC on the SHAC paper's Ant (DFlex's, exact 3-D dynamics with penalty contact) with the authors' settings.

    python examples/ant_shac.py            # the authors' 2000 epochs x 64 envs x 32 steps (4.1M env steps)
    python examples/ant_shac.py --quick    # 200 epochs (about 4 minutes): a gait that moves forward
    python examples/ant_shac.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (the deterministic policy's mean return over 16 episodes, env steps,
wall-clock), ``learning_curve.png`` (against env steps and against wall-clock), ``gait.png`` and ``gait.gif`` to
``--out``. The published anchor (the AHAC paper's rerun of these tasks, PPO on DFlex's ant, 1000-step episodes) is
6605.
"""

from lagrange.tasks import Ant
from optim import SHACConfig
from optim.locomotion_cli import locomotion_main

CONFIG = SHACConfig.ant()  # the authors' ant.yaml
QUICK = SHACConfig.ant(iterations=200)

if __name__ == "__main__":
    locomotion_main(__doc__.splitlines()[0], "runs/ant_shac", Ant.diffrl, CONFIG, QUICK, anchor=6605.0)
