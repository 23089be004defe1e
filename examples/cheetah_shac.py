"""Train SHAC on the SHAC paper's Cheetah (DFlex's half-cheetah, exact dynamics with penalty contact).

    python examples/cheetah_shac.py            # the authors' 2000 epochs x 64 envs x 32 steps (4.1M env steps)
    python examples/cheetah_shac.py --quick    # a short demo: a gait that moves forward in a few minutes
    python examples/cheetah_shac.py --resume   # continue an interrupted run

Writes ``checkpoint.eqx``, ``results.json`` (the deterministic policy's mean return over 16 episodes, env steps,
wall-clock), ``learning_curve.png`` (against env steps and against wall-clock), ``gait.png`` and ``gait.gif`` to
``--out``. No return is published for this task (the SHAC paper shows curves only).
"""

from lagrange.tasks import Cheetah
from optim import SHACConfig
from optim.locomotion_cli import locomotion_main

CONFIG = SHACConfig.cheetah()  # the authors' cheetah.yaml
QUICK = SHACConfig.cheetah(iterations=300)

if __name__ == "__main__":
    locomotion_main(__doc__.splitlines()[0], "runs/cheetah_shac", Cheetah.diffrl, CONFIG, QUICK)
