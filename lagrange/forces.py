"""Actuation: the controls' clamp into each motor's range, and the actuation matrix ``B`` (of a tree, and of the
planar backend's lowered chain)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.model.tree import Tree


def clamp_controls(chain: Tree, u: Float[ArrayLike, "*batch m"]) -> Float[Array, "*batch m"]:
    """Each control clamped into its joint's ``control_range``, as MuJoCo clamps a limited ``ctrl``.

    Args:
        chain: the :class:`lagrange.Tree`.
        u: controls, shape ``(*batch, m)``.

    Returns:
        The clamped controls, shape ``(*batch, m)``; ``u`` itself for a chain without ranges.
    """
    if chain.control_ranges is None:
        return u
    inf = float("inf")
    lo = np.array([-inf if r is None else r[0] for r in chain.control_ranges])
    hi = np.array([inf if r is None else r[1] for r in chain.control_ranges])
    return jnp.clip(u, lo.astype(u.dtype), hi.astype(u.dtype))


def actuation_matrix(chain: Tree) -> Float[Array, "n m"]:
    """The actuation matrix ``B``: ``B[actuated[k], k] = gear[k]``, zero elsewhere.

    Args:
        chain: the :class:`lagrange.Tree`.

    Returns:
        ``B``, shape ``(nv, m)``. A chain with control ranges applies ``B`` to the clamped control
        (:func:`clamp_controls`).

    Raises:
        ValueError: for a tree with muscles, whose generalized forces depend on ``q`` (no constant ``B``).
    """
    if getattr(chain, "muscles", ()):
        raise ValueError("actuation_matrix: the tree has muscles, whose generalized forces -F dL/dq depend on q: no "
                         "constant B exists; take the forces from lagrange.inverse_dynamics or forward_dynamics")
    return motor_matrix(chain)


def motor_matrix(chain: Tree) -> Float[Array, "n motors"]:
    """The motors' columns of ``B``: ``(nv, motors)``, ``B[actuated[k], k] = gear[k]`` (a tree's muscles aside)."""
    count = len(chain.actuated)
    B = jnp.zeros((chain.nv, count), dtype=jnp.result_type(float) if chain.gear is None else chain.gear.dtype)
    for k, j in enumerate(chain.actuated):
        B = B.at[j, k].set(chain.gear[k])
    return B
