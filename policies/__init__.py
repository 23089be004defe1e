"""Policies for the tasks of :mod:`lagrange.tasks`: the authors' GRU, an MLP, SHAC's actor and critic, and an
observation normaliser."""

from policies.actor_critic import Actor, Critic, DeterministicPolicy
from policies.gru import GRUPolicy
from policies.mlp import MLPPolicy
from policies.normalizer import BraxNormalizer, Normalizer

__all__ = ["GRUPolicy", "MLPPolicy", "Normalizer", "BraxNormalizer", "Actor", "Critic", "DeterministicPolicy"]
