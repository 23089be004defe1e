"""Stabilising a swing-up task at upright, and judging how far a controller brings it back.

Every task of :mod:`lagrange.tasks` ends balanced upright, an unstable equilibrium. This module is the analysis
around it: the upright state and a state's deviation from it, the linearisation of one control interval, the
discrete-time LQR gain, the LQR saturated at the task's actuator limit, and the basin of a controller (the largest
lean from which it brings the chain back to rest). How long a hold lasts along an episode is
:func:`lagrange.tasks.leaves_upright`.

    n, m = task.chain.nv, task.chain.m
    A, B = linearise(task)                                   # x' = A x + B u about upright, one interval
    K = lqr_gain(A, B, np.diag([1.0] * n + [0.01] * n), np.eye(m))
    basin(task, saturated_lqr(task, K), leans=[0.01, 0.1, 0.3], steps=3000).largest_recovered_lean

States ``x = (q, qd)`` have shape (2n,): coordinates in rad (m for a cart), velocities in rad/s (m/s); actions are
the task's, in ``[-1, 1]`` before its gear.
"""

from __future__ import annotations

from typing import NamedTuple
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from lagrange.tasks import AbstractPoleTask, TaskState, wrap

__all__ = ["upright_state", "upright_deviation", "linearise", "lqr_gain", "saturated_lqr", "Basin", "basin"]


def upright_state(task: AbstractPoleTask) -> Float[np.ndarray, " 2*n"]:
    """``(q, qd)`` of the balanced chain at rest: the first pole's joint at pi, the rest (and any cart) at 0, in the
    chain's float type."""
    x = np.zeros(2 * task.chain.nv, np.asarray(task.chain.mass).dtype)
    x[task.first_pole] = np.pi
    return x


def upright_deviation(task: AbstractPoleTask) -> Callable[[Array, Array], Float[Array, "*batch 2*n"]]:
    """``deviation(q, qd) -> dx``: the state minus upright at rest, ``q``, ``qd`` (..., n) -> (..., 2n), with the
    joint angles wrapped to ``(-pi, pi]`` (a cart's position is not)."""
    n = task.chain.nv
    x0 = jnp.asarray(upright_state(task))
    angular = jnp.arange(n) >= task.first_pole

    def deviation(q, qd):
        dq = jnp.where(angular, wrap(q - x0[:n]), q - x0[:n])
        return jnp.concatenate([dq, qd], axis=-1)

    return deviation


def linearise(task: AbstractPoleTask, x0: ArrayLike | None = None, u0: ArrayLike | None = None
              ) -> tuple[Float[np.ndarray, "2*n 2*n"], Float[np.ndarray, "2*n m"]]:
    """``(A, B)``, float64: the Jacobians of one control interval ``task.step`` at ``x0`` (2n,) and ``u0`` (m,),
    ``x' ~ x0' + A (x - x0) + B (u - u0)``, by ``jax.jacfwd`` in the chain's float type. Defaults: upright at rest and
    no action, where ``x0' = x0``. Inside ``|u0| < 1`` (the action is clipped there)."""
    n, m = task.chain.nv, task.chain.m
    dtype = upright_state(task).dtype
    x0 = jnp.asarray(upright_state(task) if x0 is None else x0, dtype)
    u0 = jnp.zeros(m, dtype) if u0 is None else jnp.asarray(u0, dtype)
    for name, v, shape in (("x0", x0, (2 * n,)), ("u0", u0, (m,))):
        if v.shape != shape:
            raise ValueError(f"linearise: {name} must have shape {shape}, got {v.shape}")

    def f(x, u):
        s = task.step(TaskState(x[:n], x[n:]), u)
        return jnp.concatenate([s.q, s.qd])

    return np.asarray(jax.jacfwd(f, 0)(x0, u0), np.float64), np.asarray(jax.jacfwd(f, 1)(x0, u0), np.float64)


def lqr_gain(A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike) -> Float[np.ndarray, "M N"]:
    """The discrete-time LQR gain ``K`` (M, N) of ``x' = A x + B u`` (A: (N, N), B: (N, M)) for the cost
    ``sum x' Q x + u' R u``, ``Q`` (N, N) symmetric positive semidefinite, ``R`` (M, M) symmetric positive definite;
    the control is ``u = -K x``. From the stabilising solution ``P`` of the Riccati equation
    (``scipy.linalg.solve_discrete_are``): ``K = (R + B' P B)^-1 B' P A``. Raises ``ValueError`` naming a bad argument,
    ``numpy.linalg.LinAlgError`` where no stabilising solution exists (``(A, B)`` not stabilisable)."""
    import scipy.linalg

    A, B, Q, R = (np.asarray(v, np.float64) for v in (A, B, Q, R))
    N = A.shape[0] if A.ndim else 0
    M = B.shape[1] if B.ndim == 2 else 0
    for name, v, shape in (("A", A, (N, N)), ("B", B, (N, M)), ("Q", Q, (N, N)), ("R", R, (M, M))):
        if v.shape != shape or N == 0 or M == 0:
            raise ValueError(f"lqr_gain: {name} must have shape {shape} (A (N, N), B (N, M), Q (N, N), R (M, M)), "
                             f"got A {A.shape}, B {B.shape}, Q {Q.shape}, R {R.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"lqr_gain: {name} must be finite")
    for name, v, definite in (("Q", Q, False), ("R", R, True)):
        scale = max(1.0, float(np.max(np.abs(v))))
        lowest = float(np.min(np.linalg.eigvalsh((v + v.T) / 2)))
        if np.max(np.abs(v - v.T)) > 1e-12 * scale or (lowest <= 0 if definite else lowest < -1e-12 * scale):
            raise ValueError(f"lqr_gain: {name} must be symmetric positive {'definite' if definite else 'semidefinite'}"
                             f", got smallest eigenvalue {lowest:.3g}")
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


def saturated_lqr(task: AbstractPoleTask, K: ArrayLike) -> Callable[[Array, Array], Float[Array, "*batch m"]]:
    """``controller(q, qd) -> u``: the LQR about upright saturated at the task's limit, ``clip(-K dx, -1, 1)``, with
    ``dx`` from :func:`upright_deviation`; ``q``, ``qd`` (..., n) -> (..., m). ``K`` (m, 2n): :func:`lqr_gain`'s."""
    n, m = task.chain.nv, task.chain.m
    K = jnp.asarray(K, upright_state(task).dtype)
    if K.shape != (m, 2 * n):
        raise ValueError(f"saturated_lqr: K must have shape (m, 2n) = {(m, 2 * n)}, got {K.shape}")
    deviation = upright_deviation(task)
    return lambda q, qd: jnp.clip(-(deviation(q, qd) @ K.T), -1.0, 1.0)


class Basin(NamedTuple):
    """:func:`basin`'s answer, per leant joint (J of them) and lean (L of them)."""

    joints: tuple[int, ...]
    """The joints leant, indices into ``q``."""
    leans: Float[np.ndarray, " L"]
    """The leans tried, rad, increasing."""
    final_error: Float[np.ndarray, "J L"]
    """The largest ``|dx|`` (rad, m, rad/s, m/s) after the rollout; NaN or inf where the state went non-finite."""
    recovered: Bool[np.ndarray, "J L"]
    """``final_error < tol`` (non-finite: not recovered)."""
    largest_recovered_lean: Float[np.ndarray, " J"]
    """The largest lean up to which every lean tried recovered (0 if the smallest did not)."""


def basin(task: AbstractPoleTask, controller: Callable, *, leans: ArrayLike, steps: int, tol: float = 1e-3,
          joints: tuple[int, ...] | None = None) -> Basin:
    """How far from upright ``controller(q, qd) -> u`` (m,) brings the chain back to rest. Each start is upright at
    rest with one joint leant by one of ``leans`` (rad, increasing; the first pole's joint leans the whole straight
    chain, a later one bends it there); it recovers when, after ``steps`` control steps of ``task.step``, every
    coordinate and velocity is within ``tol`` (rad, m, rad/s, m/s) of upright at rest. ``joints`` default to every
    pole joint. One jitted rollout, run start by start."""
    leans = np.asarray(leans, np.float64)
    poles = tuple(range(task.first_pole, task.chain.nv))
    joints = poles if joints is None else tuple(int(j) for j in joints)
    if leans.ndim != 1 or leans.size == 0 or not np.all(np.isfinite(leans)) or np.any(np.diff(leans) <= 0):
        raise ValueError(f"basin: leans must be a non-empty increasing 1-D sequence of finite angles, got {leans}")
    if not (isinstance(steps, (int, np.integer)) and steps >= 1):
        raise ValueError(f"basin: steps must be an integer >= 1, got {steps!r}")
    if not tol > 0:
        raise ValueError(f"basin: tol must be > 0, got {tol!r}")
    if not joints or any(j not in poles for j in joints):
        raise ValueError(f"basin: joints must be pole joints among {poles}, got {joints}")
    n = task.chain.nv
    x0 = upright_state(task)
    deviation = upright_deviation(task)

    def body(x, _):
        s = task.step(TaskState(x[:n], x[n:]), controller(x[:n], x[n:]))
        return jnp.concatenate([s.q, s.qd]), None

    @jax.jit
    def rollout(x):
        xT, _ = jax.lax.scan(body, jnp.asarray(x, x0.dtype), None, length=steps)
        return jnp.max(jnp.abs(deviation(xT[:n], xT[n:])))

    final_error = np.empty((len(joints), leans.size))
    for i, j in enumerate(joints):
        for k, d in enumerate(leans.tolist()):
            x = x0.copy()
            x[j] += d
            final_error[i, k] = float(rollout(jnp.asarray(x)))
    recovered = final_error < tol
    upto = np.cumprod(recovered, axis=1).sum(axis=1)  # how many leading leans recovered
    largest = np.where(upto > 0, leans[np.maximum(upto - 1, 0)], 0.0)
    return Basin(joints, leans, final_error, recovered, largest)
