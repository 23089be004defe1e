"""Rollouts of a batch of initial states, with a failure that names the member it happened to.

``jax.vmap(lagrange.simulate)`` works, but when one member's state turns non-finite the error cannot say which: under
``vmap`` a check sees the whole batch at once. :func:`simulate_batch` vmaps :func:`lagrange.simulate` unchecked and
checks the batch's final states itself, so its error names the first member that failed.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from lagrange.model.tree import Tree
from lagrange.integrate import Trajectory, simulate

__all__ = ["simulate_batch"]


def simulate_batch(
    chain: Tree,
    q0: Float[ArrayLike, "B n"],
    qd0: Float[ArrayLike, "B n"],
    controls: Float[ArrayLike, "B T m"] | Float[ArrayLike, "T m"] | Any | None,
    dt: float | Float[ArrayLike, ""],
    *args,
    check: bool = True,
    **kwargs,
) -> Trajectory:
    """:func:`lagrange.simulate` of ``B`` initial states at once (``jax.vmap``), one chain.

    Args:
        chain: the chain, shared by every member.
        q0: initial coordinates, shape ``(B, n)``.
        qd0: initial velocities, shape ``(B, n)``.
        controls: per member ``(B, T, m)``, shared ``(T, m)``, a policy callable or None (as :func:`simulate`).
        dt: the control interval [s], shared.
        *args: :func:`simulate`'s ``solver`` and ``substeps``.
        check: raise if a member's final state is not finite, naming the first such member (its index in the batch)
            and what it started from.
        **kwargs: :func:`simulate`'s keyword arguments (``steps``, ``adjoint``, ``rtol``, ...).

    Returns:
        A :class:`Trajectory` whose fields have a leading batch axis: ``q`` and ``qd`` of shape ``(B, T + 1, n)``.

    Raises:
        ValueError: ``q0`` and ``qd0`` not of shape ``(B, n)`` with one ``B``, or per-member controls of another
            ``B``; and whatever :func:`simulate` raises for its arguments.
    """
    q0, qd0 = jnp.asarray(q0), jnp.asarray(qd0)
    if q0.ndim != 2 or q0.shape[1] != chain.nq or qd0.ndim != 2 or qd0.shape != (q0.shape[0], chain.nv):
        raise ValueError(f"simulate_batch: q0 and qd0 must have shapes (B, {chain.nq}) and (B, {chain.nv}) for this "
                         f"tree, got {q0.shape} and {qd0.shape}")
    batch = q0.shape[0]
    per_member = controls is not None and not callable(controls) and jnp.ndim(controls) == 3
    if per_member and jnp.shape(controls)[0] != batch:
        raise ValueError(f"simulate_batch: controls of shape (B, T, m) must have B = {batch} (q0's), got "
                         f"{jnp.shape(controls)}")
    q0, qd0 = _finite_members("q0", q0), _finite_members("qd0", qd0)
    if per_member:
        controls = _finite_members("controls", jnp.asarray(controls))
    run = jax.vmap(lambda q, qd, u: simulate(chain, q, qd, u, dt, *args, check=False, **kwargs),
                   in_axes=(0, 0, 0 if per_member else None))
    traj = run(q0, qd0, controls)
    if not check:
        return traj
    last = jnp.concatenate([traj.q[:, -1], traj.qd[:, -1]], axis=1)
    bad = ~jnp.all(jnp.isfinite(last), axis=1)
    messages = [f"lagrange.simulate_batch: the state of member {i} of {batch} became non-finite (NaN/Inf) (the first "
                f"that did); simulate(chain, q0[{i}], qd0[{i}], ...) alone reproduces it: reduce dt, raise substeps or "
                "check the chain's parameters and that member's start and controls" for i in range(batch)]
    last = eqx.branched_error_if(last, jnp.any(bad), jnp.argmax(bad), messages)
    n = chain.nq
    q = traj.q.at[:, -1].set(last[:, :n])
    qd = traj.qd.at[:, -1].set(last[:, n:])
    return Trajectory(t=traj.t, q=q, qd=qd, u=traj.u)


def _finite_members(name: str, x):
    """``x`` (batch first) checked to be finite, the error naming the first member that is not: now when concrete,
    when run when traced."""
    if not isinstance(x, jax.core.Tracer):
        bad = np.argwhere(~np.isfinite(np.asarray(x)))
        if len(bad):
            at = tuple(int(i) for i in bad[0])
            raise ValueError(f"simulate_batch: {name} must be finite, got {float(np.asarray(x)[at])} in member {at[0]} "
                             f"at index {at[1:]}")
        return x
    bad = ~jnp.all(jnp.isfinite(x.reshape(x.shape[0], -1)), axis=1)
    return eqx.branched_error_if(x, jnp.any(bad), jnp.argmax(bad), [
        f"lagrange.simulate_batch: {name} of member {i} of {x.shape[0]} is not finite (NaN or Inf)"
        for i in range(x.shape[0])])
