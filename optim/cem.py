"""The cross-entropy method over flat policy parameters (the paper's gradient-free ablation).

CE-APG's loop with no APG steps (:func:`optim.ce_apg.make_trainer`): each candidate's fitness is its mean return over
``episodes`` random-start episodes, and the diagonal Gaussian is refitted to the elites.
"""

from __future__ import annotations

import dataclasses

from optim.ce_apg import CEAPGConfig

__all__ = ["CEMConfig"]


@dataclasses.dataclass(frozen=True)
class CEMConfig(CEAPGConfig):
    """The paper's CEM ablation: :class:`optim.CEAPGConfig` with no APG steps; a candidate's fitness is the mean return
    of its ``episodes`` episodes. The other fields are :class:`optim.CEAPGConfig`'s.

    Attributes:
        iterations (int): CE iterations (paper: 2000).
        apg_steps (int): must be 0.
        fitness_window (int): 1 (one batch of episodes per candidate).
    """

    iterations: int = 2000
    apg_steps: int = 0
    fitness_window: int = 1

    def __post_init__(self):
        if self.apg_steps != 0:
            raise ValueError(f"CEMConfig.apg_steps must be 0 (CEM has no gradient steps), got {self.apg_steps!r}; "
                             f"use CEAPGConfig for APG steps")
        super().__post_init__()
