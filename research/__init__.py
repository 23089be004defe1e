"""Experiments apart from the product: each is run from the repository root as ``python -m research.<name>``."""
