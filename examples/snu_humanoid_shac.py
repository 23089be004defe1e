"""Train SHAC on the SHAC paper's muscle-actuated humanoid (DFlex's SNU humanoid: MASS's lower body, 152 muscles)
with the authors' settings.

    python examples/snu_humanoid_shac.py            # the authors' 2000 epochs x 64 envs x 32 steps (4.1M env steps)
    python examples/snu_humanoid_shac.py --quick    # 100 epochs, 12-15 minutes: a demo, not yet a gait
    python examples/snu_humanoid_shac.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (the deterministic policy's mean return over 16 episodes, env steps,
wall-clock), ``learning_curve.png`` (against env steps and against wall-clock), ``gait.png`` and ``gait.gif`` to
``--out``. The published anchor (the AHAC paper's rerun of this task, PPO's IQM maximum) is 4246; its SHAC reached
about 6114 (a different action mapping and settings: ``docs/locomotion.md``).
"""

from lagrange.tasks import SNUHumanoid
from optim import SHACConfig
from optim.locomotion_cli import locomotion_main

CONFIG = SHACConfig.snu_humanoid()  # the authors' snu_humanoid.yaml
QUICK = SHACConfig.snu_humanoid(iterations=100)

if __name__ == "__main__":
    locomotion_main(__doc__.splitlines()[0], "runs/snu_humanoid_shac", SNUHumanoid.diffrl, CONFIG, QUICK,
                    actor_units=(512, 256), anchor=4246.0)
