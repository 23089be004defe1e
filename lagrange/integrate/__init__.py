"""Time integration on diffrax: :func:`simulate` and :func:`step` (:mod:`~lagrange.integrate.rollout`), one control
interval of a solver (:mod:`~lagrange.integrate.interval`), the solvers (:mod:`~lagrange.integrate.solvers`) and
batched rollouts (:mod:`~lagrange.integrate.batch`)."""

from lagrange.integrate.rollout import Trajectory, simulate, step

__all__ = ["Trajectory", "simulate", "step"]
