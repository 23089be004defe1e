"""Policies for the tasks of :mod:`lagrange.tasks`: the authors' GRU, an MLP, and an observation normaliser."""

from policies.gru import GRUPolicy
from policies.mlp import MLPPolicy
from policies.normalizer import Normalizer

__all__ = ["GRUPolicy", "MLPPolicy", "Normalizer"]
