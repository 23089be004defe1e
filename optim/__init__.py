"""Training policies through differentiable tasks: CE-APG, PAPG, CEM, APG and SHAC behind one entry point.

An algorithm is a typed config of settings (:class:`CEAPGConfig`, :class:`PAPGConfig`, :class:`CEMConfig`,
:class:`APGConfig`, :class:`SHACConfig`); :func:`train` runs any of them on a task and a policy passed as objects, with
one progress bar, one checkpoint format, resume and one learning-curve record. :func:`apg_steps` is the one APG inner
step (its ``objective`` a parameter); :func:`episode` and :func:`evaluate` roll a policy out.
"""

from optim import checkpoint, devices
from optim.apg import APGConfig
from optim.base import AlgorithmConfig, Trainer, scan_train
from optim.bptt import APGResult, apg_steps, flatten_policy, mean_return_loss
from optim.ce_apg import CEAPGConfig
from optim.cem import CEMConfig
from optim.episode import Episode, episode, evaluate
from optim.papg import PAPGConfig
from optim.shac import SHACConfig
from optim.train import TrainResult, load, train

__all__ = ["train", "load", "TrainResult", "AlgorithmConfig", "Trainer", "scan_train", "APGConfig", "CEAPGConfig",
           "CEMConfig", "PAPGConfig", "SHACConfig", "apg_steps", "APGResult", "mean_return_loss", "flatten_policy",
           "episode", "evaluate", "Episode", "checkpoint", "devices"]
