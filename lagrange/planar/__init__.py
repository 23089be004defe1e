"""The planar backend: a tree whose joints all move in one plane, derived by the unrolled derivation
(:mod:`~lagrange.planar.unrolled`) below ``RECURSIVE_MIN`` links and by the recursive algorithms
(:mod:`~lagrange.planar.recursive`) above."""
