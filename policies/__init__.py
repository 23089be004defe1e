"""Policies for the tasks of :mod:`lagrange.tasks`: the authors' GRU, an MLP, SHAC's actor and critic, and an
observation normaliser. Every policy is a :class:`AbstractPolicy` (``policy(obs, hidden, reset) -> (action,
hidden)``, built for a task by ``for_task`` and redrawn by ``reinit``)."""

from policies.actor_critic import Actor, Critic
from policies.base import AbstractFeedForwardPolicy, AbstractPolicy
from policies.gru import GRUPolicy
from policies.mlp import MLPPolicy
from policies.normalizer import BraxNormalizer, Normalizer

__all__ = ["AbstractPolicy", "AbstractFeedForwardPolicy", "GRUPolicy", "MLPPolicy", "Actor", "Critic", "Normalizer",
           "BraxNormalizer"]
