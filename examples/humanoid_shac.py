"""Train SHAC on the SHAC paper's Humanoid (DFlex's, exact 3-D dynamics, penalty contact) with the authors' settings.

    python examples/humanoid_shac.py            # the authors' 2000 epochs x 64 envs x 32 steps (4.1M env steps)
    python examples/humanoid_shac.py --quick    # 500 epochs (about 35 minutes): a crouched run forward, then a fall
    python examples/humanoid_shac.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (the deterministic policy's mean return over 16 episodes, env steps,
wall-clock), ``learning_curve.png`` (against env steps and against wall-clock), ``gait.png`` and ``gait.gif`` to
``--out``. The published anchor (the AHAC paper's rerun of these tasks, PPO on DFlex's humanoid, 1000-step episodes)
is 7293.
"""

from lagrange.tasks import Humanoid
from optim import SHACConfig
from optim.locomotion_cli import locomotion_main

CONFIG = SHACConfig.humanoid()  # the authors' humanoid.yaml
QUICK = SHACConfig.humanoid(iterations=500)

if __name__ == "__main__":
    locomotion_main(__doc__.splitlines()[0], "runs/humanoid_shac", Humanoid.diffrl, CONFIG, QUICK,
                    actor_units=(256, 128), anchor=7293.0)
