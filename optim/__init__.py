"""Optimisers that train policies through differentiable tasks: APG, CEM, CE-APG, PAPG, SHAC."""

from optim import apg, ce_apg, cem, checkpoint, devices, papg, shac
from optim._loop import run
from optim.apg import APGConfig, episode, evaluate
from optim.ce_apg import CEAPGConfig
from optim.papg import PAPGConfig
from optim.shac import SHACConfig

__all__ = ["apg", "ce_apg", "cem", "checkpoint", "devices", "papg", "shac", "APGConfig", "CEAPGConfig", "PAPGConfig",
           "SHACConfig", "episode", "evaluate", "run"]
