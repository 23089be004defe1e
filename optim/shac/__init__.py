"""Short-horizon actor-critic (SHAC, Xu et al. 2022) as its authors ran it (NVlabs/DiffRL ``algorithms/shac.py``).

One epoch:

1. **Actor.** ``num_envs`` environments continue from where the last window left them, with the
   gradient cut there (``stop_gradient`` of the carried state). For ``short_horizon`` steps the
   stochastic actor acts, ``a = tanh(mu(obs) + exp(log_std) eps)``, and the simulation is
   differentiated through. The loss sums, for every environment at the window's end and at every
   episode end inside the window, minus the discounted reward since the last cut plus ``gamma^k`` times
   the *target* critic's value of the state reached (the gradient flows into that state), and is
   divided by ``short_horizon * num_envs``. An episode that ends inside the window is reset with the
   gradient cut (the reset state is a fresh sample), and its discount restarts at 1. One Adam step
   (betas 0.7, 0.95) with the gradient's global norm clipped to ``actor_grad_norm``.
2. **Critic.** TD(lambda) targets from the window's rewards and the target critic's values, truncated
   at episode ends and at the window's end (:func:`td_lambda_targets`); then ``critic_iterations``
   passes over ``critic_minibatches`` contiguous minibatches (the authors' unshuffled split) of plain
   MSE, each an Adam step with the gradient norm clipped to ``critic_grad_norm``.
3. **Target critic.** ``target = alpha target + (1 - alpha) critic`` (:func:`soft_update`).

Both learning rates fall linearly from their start to ``lr_end`` over ``epochs`` (epoch ``e`` uses
``lr0 + (lr_end - lr0) e / epochs``). Observations are normalised by a running mean/variance; inside
a window the statistics frozen at its start are used, and they are updated with every observation the
window saw (its start and every step). Evaluation is deterministic: ``a = tanh(mu(obs))``.

Actor and critic are MLPs ``[64, 64]`` of Linear -> ELU -> LayerNorm; the actor's output layer is linear
(the mean), its log-std a state-independent vector initialised to -1; the actor's layers keep the
default (PyTorch-style uniform) initialisation and the critic's are orthogonal with gain sqrt(2) and
zero biases, as in the authors' code.

Train it with :func:`optim.train` (``SHACConfig`` is its config; the actor, a :class:`policies.Actor`, is passed as
the policy); the environments are sharded over every device.

Differences from the authors' code: a non-finite actor or critic gradient skips that update (and is
counted in the metrics) instead of raising; the running-statistics prior is a count of 0 (theirs 1e-4);
the episode return reported during training is that of the stochastic policy, as theirs.
"""

from optim.shac.config import SHACConfig
from optim.shac.losses import actor_loss, soft_update, td_lambda_targets
from optim.shac.trainer import SHACState, make_trainer

__all__ = ["SHACConfig", "SHACState", "make_trainer", "td_lambda_targets", "soft_update", "actor_loss"]
