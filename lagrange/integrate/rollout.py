"""Time integration of a tree under piecewise-constant controls, on diffrax.

:func:`simulate` rolls a tree out over ``T`` control intervals of length ``dt``; :func:`step`
advances one interval (for RL loops). Within an interval the control is held constant and the
solver takes ``substeps`` fixed steps of ``dt / substeps``, or adaptive steps when ``rtol`` and
``atol`` are given.

Fixed-step explicit Runge-Kutta solvers (``RK4``, ``Euler``, ``Tsit5``, ``Dopri5``,
``Dopri8``, any diffrax ERK) are run from their diffrax Butcher tableau, unrolled, with zero
coefficients and unused stages dropped at trace time and differentiated by plain reverse-mode
autodiff through the ``scan`` (the fastest choice for short, fixed-step horizons). Passing a
diffrax ``adjoint`` (e.g. ``diffrax.RecursiveCheckpointAdjoint()``,
``diffrax.BacksolveAdjoint()``), or asking for adaptive steps, runs each interval through
``diffrax.diffeqsolve`` instead; both paths give the same numbers to round-off.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.dynamics import backend, prepare
from lagrange.integrate.interval import check_solver, interval_map
from lagrange.integrate.solvers import RK4, MomentumEuler, SemiImplicitEuler
from lagrange.backend import AbstractBackend
from lagrange.model.tree import Tree


class Trajectory(eqx.Module):
    """A rolled-out trajectory over ``T`` intervals: times ``t`` [s], shape ``(T+1,)``; joint coordinates ``q``
    [rad or m] and velocities ``qd`` [rad/s or m/s], shape ``(T+1, n)``; and the controls ``u``, shape
    ``(T, m)``, that were applied over each interval (``times = T + 1``, ``intervals = T``)."""

    t: Float[Array, " times"]
    q: Float[Array, "times n"]
    qd: Float[Array, "times n"]
    u: Float[Array, "intervals m"]


def _check_dt(dt):
    if isinstance(dt, jax.core.Tracer):
        return
    kind = np.asarray(dt).dtype if hasattr(dt, "dtype") or isinstance(dt, (bool, complex)) else None
    if isinstance(dt, bool) or kind == np.bool_ or (kind is not None and np.issubdtype(kind, np.complexfloating)):
        raise TypeError(f"dt must be a positive real number of seconds, got {dt!r}")
    try:
        v = float(dt)
    except (TypeError, ValueError) as err:
        raise TypeError(f"dt must be a positive real number of seconds, got {dt!r}") from err
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"dt must be a finite number > 0 seconds, got {v}")


def _check_substeps(substeps):
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")


def _finite(name: str, x):
    """``x`` checked to be finite: now (a ``ValueError`` naming ``name`` and the first bad entry) when concrete, when
    run (``eqx.error_if``) when traced; ``None`` passes."""
    if x is None:
        return x
    if not isinstance(x, jax.core.Tracer):
        bad = np.argwhere(~np.isfinite(np.asarray(x)))
        if len(bad):
            at = tuple(int(i) for i in bad[0])
            raise ValueError(f"{name} must be finite, got {float(np.asarray(x)[at])} at index {at}")
        return x
    return eqx.error_if(x, ~jnp.all(jnp.isfinite(x)), f"lagrange.simulate: {name} is not finite (NaN or Inf)")


def _check_max_steps(max_steps):
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
        raise ValueError(f"max_steps must be an integer >= 1 (solver steps per interval), got {max_steps!r}")


def _check_steps(steps):
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1):
        raise ValueError(f"steps must be None or an integer >= 1 (the number of control intervals), got {steps!r}")


def _float_dtype(tree: Tree, *arrays):
    """The float dtype a rollout runs in: the tree's parameters' promoted with that of every floating input."""
    leaves = [x for x in jax.tree_util.tree_leaves(tree) if eqx.is_inexact_array(x)]
    floats = [x.dtype for x in arrays if x is not None and jnp.issubdtype(x.dtype, jnp.floating)]
    return jnp.result_type(*[x.dtype for x in leaves], *floats) if leaves or floats else jnp.result_type(float)


def _real_array(name: str, x):
    """``x`` as an array, refusing booleans and complex numbers by name."""
    x = jnp.asarray(x)
    if x.dtype == jnp.bool_ or jnp.issubdtype(x.dtype, jnp.complexfloating):
        raise TypeError(f"{name} must hold real numbers (integers or floats, converted to the chain's float dtype), "
                        f"got dtype {x.dtype}")
    return x


def _check_state(b: AbstractBackend, q, qd):
    for name, x, size in (("q0", q, b.nq), ("qd0", qd, b.nv)):
        if jnp.shape(x) != (size,):
            raise ValueError(f"{name} must have shape ({size},) for this tree, got {jnp.shape(x)}")


def simulate(
    tree: Tree,
    q0: Float[ArrayLike, " n"],
    qd0: Float[ArrayLike, " n"],
    controls: Float[ArrayLike, "T m"] | Callable[[Float[Array, ""], Float[Array, " n"], Float[Array, " n"]],
                                                 Float[ArrayLike, " m"]] | None,
    dt: float | Float[ArrayLike, ""],
    solver: diffrax.AbstractSolver | SemiImplicitEuler | MomentumEuler = RK4(),
    substeps: int = 1,
    *,
    steps: int | None = None,
    adjoint: diffrax.AbstractAdjoint | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    max_steps: int = 4096,
    check: bool = True,
    checkpoint: bool = True,
    general: bool = False,
) -> Trajectory:
    """Roll a tree out from ``(q0, qd0)`` over ``T`` intervals of ``dt`` seconds.

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`~lagrange.chain.Chain` is one).
        q0: initial joint coordinates [rad or m], shape ``(n,)`` (a tree's: ``(nq,)``, its quaternions normalised
            here, a zero one refused); integers and lower-precision floats are converted to the chain's float
            dtype, booleans and complex numbers refused.
        qd0: initial joint velocities [rad/s or m/s], shape ``(n,)`` (a tree's: ``(nv,)``); converted as ``q0``.
        controls: an array ``(T >= 1, m)`` held constant over each interval, or a policy
            ``controls(t, q, qd) -> u`` of shape ``(m,)`` evaluated at each interval's start
            (then ``steps=T`` is required). ``None`` for an unactuated chain (with ``steps``).
        dt: control interval [s], > 0.
        solver: a solver instance from :mod:`lagrange.integrate.solvers` (default :class:`RK4`).
        substeps: fixed solver steps per interval (the initial step when adaptive), an integer >= 1.
        steps: ``T``, the number of control intervals, an integer >= 1: required with a policy callable or
            ``controls=None``; with an array it must equal its length, or be None.
        adjoint: ``None`` for direct reverse-mode through the unrolled steps, or a diffrax
            adjoint to run every interval through ``diffrax.diffeqsolve``.
        rtol: relative tolerance of adaptive steps (embedded-error solvers only; give ``atol`` too), or None.
        atol: absolute tolerance of adaptive steps, or None.
        max_steps: with adaptive steps, the most solver steps one control interval may take.
        check: raise (``eqx.error_if``) if the final state is not finite, which also reports a
            mass matrix met singular on the way; check the chain's parameters, ``q0``, ``qd0`` and the controls.
            Under ``jax.vmap`` the error cannot name the member: :func:`lagrange.simulate_batch` does.
        checkpoint: with fixed steps and ``adjoint=None``, recompute each interval's
            intermediates in the backward pass (``jax.checkpoint``) instead of storing them:
            memory O(T) states only, and 2-3x faster gradients for cheap dynamics on a CPU.
        general: run the general rigid-body algorithms even on a planar tree (:func:`lagrange.dynamics.backend`), a
            cross-check of the planar backend; ``False`` (the default) lets the tree's structure choose.

    Returns:
        A :class:`Trajectory` with ``t``, ``q``, ``qd`` of leading length ``T + 1`` and ``u``.

    Raises:
        ValueError: a shape that does not match the chain, ``T`` or ``steps`` < 1 or not an integer, ``dt <= 0``,
            ``substeps < 1``, or an unknown solver setting, naming the argument.
        TypeError: a ``dt`` that is not a real number (a bool included), boolean or complex ``q0``, ``qd0`` or
            controls.
        equinox.EquinoxRuntimeError: (when run, with ``check=True``) if the final state is not finite.
    """
    b = backend(tree, check=check, general=general, name="tree")  # the tree checked once, before the loop
    check_solver(solver)
    _check_dt(dt)
    _check_substeps(substeps)
    _check_steps(steps)
    _check_max_steps(max_steps)
    q0, qd0 = _real_array("q0", q0), _real_array("qd0", qd0)
    _check_state(b, q0, qd0)
    arrays = not callable(controls) and controls is not None
    us = _real_array("controls", controls) if arrays else None
    dtype = _float_dtype(tree, q0, qd0, us)
    q0, qd0 = q0.astype(dtype), qd0.astype(dtype)
    b.check_coordinates("q0", q0)
    q0 = b.normalize(q0)
    if check:
        q0, qd0, us = (_finite(name, x) for name, x in (("q0", q0), ("qd0", qd0), ("controls", us)))
    interval = interval_map(b, solver, dt, substeps, adjoint, rtol, atol, max_steps)
    if checkpoint and adjoint is None and rtol is None and atol is None:
        interval = jax.checkpoint(interval)

    if callable(controls):
        if steps is None:
            raise ValueError("steps (the number of intervals, an int >= 1) is required with a policy callable")
        policy = controls

        def body(carry, k):
            q, qd = carry
            u = _real_array("the policy's u", policy(k * dt, q, qd))
            if u.shape != (b.m,):
                raise ValueError(f"the policy must return u of shape ({b.m},), got {u.shape}")
            u = u.astype(dtype)
            out = interval(q, qd, u)
            return out, (out, u)

        (qT, qdT), ((qs, qds), us) = jax.lax.scan(body, (q0, qd0), jnp.arange(steps))
    else:
        if controls is None:
            if steps is None:
                raise ValueError("controls=None needs steps (the number of intervals, an int >= 1)")
            us = jnp.zeros((steps, b.m), dtype)
        if us.ndim != 2 or us.shape[1] != b.m:
            raise ValueError(f"controls must have shape (T, {b.m}) for this tree, got {us.shape}")
        if us.shape[0] < 1:
            raise ValueError(f"controls must hold at least one control interval: shape (T >= 1, {b.m}), got "
                             f"{us.shape}")
        us = us.astype(dtype)
        if steps is not None and steps != us.shape[0]:
            raise ValueError(f"steps={steps} disagrees with controls of length {us.shape[0]}")

        def body(carry, u):
            out = interval(*carry, u)
            return out, out

        (qT, qdT), (qs, qds) = jax.lax.scan(body, (q0, qd0), us)

    if check:
        # Check the final state only (NaN/Inf propagate forward) and tie the check to both
        # outputs through their last row, so it is neither dead code nor a copy of the trajectory.
        last = jnp.concatenate([qT, qdT])
        last = eqx.error_if(
            last,
            ~jnp.all(jnp.isfinite(last)),
            "lagrange.simulate: the state became non-finite (NaN/Inf); reduce dt, raise substeps "
            "or check the chain's parameters and the controls. A mass matrix that is singular somewhere on the way "
            "(some motion of the joints moves no mass, inertia or armature there, e.g. a massless link carrying a "
            "point mass as the joints align) does this too: give the links an inertia > 0 or the joints an "
            "armature > 0",
        )
        qT, qdT = last[: qT.shape[0]], last[qT.shape[0]:]
    q = jnp.concatenate([q0[None], qs[:-1], qT[None]])
    qd = jnp.concatenate([qd0[None], qds[:-1], qdT[None]])
    t = jnp.arange(q.shape[0], dtype=q.dtype) * dt
    return Trajectory(t=t, q=q, qd=qd, u=us)


def step(
    tree: Tree,
    q: Float[ArrayLike, "*batch n"],
    qd: Float[ArrayLike, "*batch n"],
    u: Float[ArrayLike, "*batch m"] | None,
    dt: float | Float[ArrayLike, ""],
    solver: diffrax.AbstractSolver | SemiImplicitEuler | MomentumEuler = RK4(),
    substeps: int = 1,
    *,
    adjoint: diffrax.AbstractAdjoint | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    max_steps: int = 4096,
    general: bool = False,
) -> tuple[Float[Array, "*batch n"], Float[Array, "*batch n"]]:
    """Advance ``(q, qd)`` by one interval of ``dt`` seconds under the constant control ``u``.

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`~lagrange.chain.Chain` is one).
        q: joint coordinates [rad or m], shape ``(*batch, n)`` (leading batch dimensions for fixed-step solvers
            only); converted as for :func:`simulate`.
        qd: joint velocities [rad/s or m/s], shape ``(*batch, n)``.
        u: controls, shape ``(*batch, m)``; ``None`` for no control.
        dt: the interval [s], > 0.
        solver: as for :func:`simulate`.
        substeps: as for :func:`simulate`.
        adjoint: as for :func:`simulate`.
        rtol: as for :func:`simulate`.
        atol: as for :func:`simulate`.
        max_steps: as for :func:`simulate`.
        general: as for :func:`simulate`.

    Returns:
        The new ``(q, qd)``, each of shape ``(*batch, n)``.

    Raises:
        ValueError, TypeError: as :func:`simulate`'s, naming the argument.

    Pure and cheap: it does not check for non-finite values (see :func:`simulate`).
    """
    check_solver(solver)
    _check_dt(dt)
    _check_substeps(substeps)
    _check_max_steps(max_steps)
    q, qd = _real_array("q", q), _real_array("qd", qd)
    u = None if u is None else _real_array("u", u)
    dtype = _float_dtype(tree, q, qd, u)
    q, qd, u = q.astype(dtype), qd.astype(dtype), None if u is None else u.astype(dtype)
    b = prepare(tree, check=False, general=general, q=q, qd=qd, u=u)
    return interval_map(b, solver, dt, substeps, adjoint, rtol, atol, max_steps)(q, qd, u)
