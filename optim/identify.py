"""System identification: fit a tree's physical parameters to observed trajectories through ``lagrange.simulate``.

:func:`identify` minimises the squared error between simulated and observed windows of a trajectory (each window
restarted from its observed first state, so the error does not compound over a long horizon) over a parameter vector
``theta`` that ``make_chain(theta)`` turns into a :class:`lagrange.Tree` (a planar :class:`lagrange.chain.Chain` or a
3-D tree of bodies, balls and free joints): L-BFGS (``optax.lbfgs``, with its zoom line
search) on the gradient ``jax.grad`` takes through the solver's steps, all iterations in one compiled ``lax.scan``.
Any parameter a tree has can be identified this way (masses, lengths, inertias, damping, gears, gravity), and any
parametrisation (a log scale keeps a mass positive; a density ties a link's inertia to its mass).

A fit whose iterates leave the parameters' valid range (a mass driven negative, a step too large for the guessed
chain) does not abort: the loss goes non-finite there, :func:`identify` keeps the best parameters found before, and
its result (and a warning) says at which iteration, on which windows and with which ``theta`` the simulation failed.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array, ArrayLike, Float

import lagrange as lg
from lagrange.model.tree import Tree

__all__ = ["Identified", "identify"]


class Identified(NamedTuple):
    """What :func:`identify` returns.

    Attributes:
        theta (Float[Array, "p"]): the best parameters found: those of the lowest finite loss.
        chain (Tree): ``make_chain(theta)``.
        losses (Float[Array, "iterations+1"]): the loss before every iteration and after the last (non-finite where
            the simulation failed).
        best_iteration (int): the index into ``losses`` of ``theta``'s loss.
        failure (str | None): None when every loss was finite; else where and why the fit failed (the first
            iteration whose loss or gradient went non-finite, the windows whose simulation did, the ``theta`` there).
    """

    theta: Float[Array, " p"]
    chain: Tree
    losses: Float[Array, " iterations+1"]
    best_iteration: int = 0
    failure: str | None = None


def identify(
    make_chain: Callable[[Float[Array, " p"]], Tree],
    theta0: Float[ArrayLike, " p"],
    states: Float[ArrayLike, "W T+1 nq+nv"],
    controls: Float[ArrayLike, "W T m"] | None,
    dt: float,
    solver=lg.RK4(),
    *,
    iterations: int = 100,
) -> Identified:
    """Fit ``theta`` so that ``make_chain(theta)`` reproduces observed windows of trajectories.

    Args:
        make_chain: ``theta -> Tree``, differentiable in ``theta``.
        theta0: the starting guess, shape ``(p,)``.
        states: ``W`` observed windows of ``T`` steps, each row ``(q, qd)``: shape ``(W, T + 1, nq + nv)``.
        controls: the controls held over each step, ``(W, T, m)``; ``None`` for a chain without actuators.
        dt: the step [s], > 0; ``solver`` the integrator that produced (or models) the data.
        iterations: L-BFGS iterations, >= 1.

    The loss is the mean squared error of the simulated windows against ``states[:, 1:]``, every coordinate and
    velocity divided by the standard deviation of its change per step in the data (so that positions and velocities,
    metres and radians weigh alike).

    Raises:
        ValueError: for shapes that do not match the tree, ``dt <= 0`` or ``iterations < 1``.
        TypeError: for a ``make_chain`` that does not return a :class:`lagrange.Tree`.
    """
    theta0 = jnp.asarray(theta0)
    states = jnp.asarray(states)
    chain0 = make_chain(theta0)
    if not isinstance(chain0, Tree):
        raise TypeError(f"identify: make_chain(theta) must return a lagrange.Tree (a lagrange.chain.Chain is one), "
                        f"got {type(chain0).__name__}")
    for name, data in (("states", states), ("controls", controls)):
        if data is not None and not bool(jnp.all(jnp.isfinite(jnp.asarray(data)))):
            raise ValueError(f"identify: {name} must be finite; the data hold a NaN or an infinity at "
                             f"{np.argwhere(~np.isfinite(np.asarray(data)))[0].tolist()}")
    n, m = chain0.nq, chain0.m
    width = chain0.nq + chain0.nv
    if states.ndim != 3 or states.shape[-1] != width or states.shape[1] < 2:
        raise ValueError(f"identify: states must have shape (windows, T + 1 >= 2, nq + nv = {width}), got "
                         f"{states.shape}")
    windows, steps = states.shape[0], states.shape[1] - 1
    if m:
        if controls is None or jnp.shape(controls) != (windows, steps, m):
            raise ValueError(f"identify: controls must have shape (windows, T, m) = {(windows, steps, m)}, got "
                             f"{None if controls is None else jnp.shape(controls)}")
        controls = jnp.asarray(controls, states.dtype)
    try:
        positive = not isinstance(dt, bool) and float(dt) > 0
    except (TypeError, ValueError):
        positive = False
    if not positive:
        raise ValueError(f"identify: dt must be a number > 0 seconds, got {dt!r}")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise ValueError(f"identify: iterations must be an integer >= 1, got {iterations!r}")
    iterations = int(iterations)
    target = states[:, 1:]
    scale = jnp.std(target - states[:, :-1], axis=(0, 1))
    scale = jnp.where(scale > 0, scale, 1.0)

    def scaled_errors(theta):
        """The simulated windows' errors, scaled, ``(W, T, nq + nv)``; non-finite where a simulation failed."""
        chain = make_chain(theta)

        def window(x, u):
            tr = lg.simulate(chain, x[0, :n], x[0, n:], u, dt, solver, steps=steps, check=False)
            return jnp.concatenate([tr.q[1:], tr.qd[1:]], axis=-1)

        sim = jax.vmap(window)(states, controls) if m else jax.vmap(lambda x: window(x, None))(states)
        return (sim - target) / scale

    def loss(theta):
        return jnp.mean(scaled_errors(theta) ** 2)

    def failed_windows(theta) -> list[int]:
        return np.flatnonzero(~np.all(np.isfinite(np.asarray(jax.jit(scaled_errors)(theta))), axis=(1, 2))).tolist()

    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss)

    def step(carry, i):
        theta, state, best, best_value, best_at, bad_theta, failed_at = carry
        value, grad = value_and_grad(theta, state=state)
        finite = jnp.isfinite(value) & jnp.all(jnp.isfinite(grad))
        better = finite & (value < best_value)
        best, best_value, best_at = (jnp.where(better, theta, best), jnp.where(better, value, best_value),
                                     jnp.where(better, i, best_at))
        first = ~finite & (failed_at < 0)
        bad_theta, failed_at = jnp.where(first, theta, bad_theta), jnp.where(first, i, failed_at)
        updates, state = opt.update(grad, state, theta, value=value, grad=grad, value_fn=loss)
        return (optax.apply_updates(theta, updates), state, best, best_value, best_at, bad_theta, failed_at), value

    @eqx.filter_jit  # a run-time check that fails inside raises EquinoxRuntimeError (jax.jit: an opaque one)
    def fit(theta):
        minus_one = jnp.asarray(-1)
        init = (theta, opt.init(theta), theta, jnp.asarray(jnp.inf, loss(theta).dtype), minus_one, theta, minus_one)
        (theta, _, best, best_value, best_at, bad_theta, failed_at), values = jax.lax.scan(
            step, init, jnp.arange(iterations))
        return theta, jnp.append(values, loss(theta)), best, best_value, best_at, bad_theta, failed_at

    try:
        final, losses, best, best_value, best_at, bad_theta, failed_at = fit(theta0)
    except eqx.EquinoxRuntimeError as err:  # a run-time check of the chain's parameters, inside the compiled fit
        return _fit_by_iterations(theta0, iterations, opt, value_and_grad, loss, make_chain, err)
    last, failed_at = float(losses[-1]), int(failed_at)
    if failed_at < 0 and np.isfinite(last):  # the fit as L-BFGS ends it
        return Identified(final, make_chain(final), losses, iterations, None)
    if failed_at < 0:
        failed_at, bad_theta = iterations, final
    theta, k = (final, iterations) if np.isfinite(last) and last < float(best_value) else (best, int(best_at))
    if k < 0:
        raise ValueError(f"identify: the loss or its gradient is not finite at theta0 = {np.asarray(theta0).tolist()} "
                         f"(the simulation of windows {failed_windows(theta0)} fails there, or the parametrisation "
                         f"has no derivative); start from parameters the chain can be simulated with")
    failure = (f"identify: the loss or its gradient went non-finite at iteration {failed_at}, with theta = "
               f"{np.asarray(bad_theta).tolist()} (the simulation of windows {failed_windows(bad_theta)} failed: "
               f"parameters out of their valid range, or a step dt too large for them); returning the best theta "
               f"found, at iteration {k} (loss {float(losses[k]):.6g})")
    warnings.warn(failure, RuntimeWarning, stacklevel=2)
    return Identified(theta, make_chain(theta), losses, k, failure)


def _fit_by_iterations(theta0, iterations, opt, value_and_grad, loss, make_chain, error) -> Identified:
    """The fit one compiled iteration at a time, after the compiled fit stopped on a run-time check (an
    ``eqx.error_if`` of the chain's parameters, met at ``theta`` or at a trial point of the line search): it stops at
    the iteration that raises it and returns the best parameters found before."""

    @eqx.filter_jit
    def one(theta, state):
        value, grad = value_and_grad(theta, state=state)
        updates, state = opt.update(grad, state, theta, value=value, grad=grad, value_fn=loss)
        return optax.apply_updates(theta, updates), state

    value_of = eqx.filter_jit(loss)
    theta, state = jnp.asarray(theta0), opt.init(jnp.asarray(theta0))
    values, best, best_value, failure = [], theta, np.inf, None
    for i in range(iterations + 1):
        try:
            value = float(value_of(theta))
        except eqx.EquinoxRuntimeError as err:
            failure = f"iteration {i}: the loss at theta = {np.asarray(theta).tolist()} failed a run-time check"
            error = err
            break
        values.append(value)
        if np.isfinite(value) and value < best_value:
            best, best_value = theta, value
        if i == iterations:
            break
        try:
            theta, state = one(theta, state)
        except eqx.EquinoxRuntimeError as err:
            failure = (f"iteration {i}: its line search from theta = {np.asarray(theta).tolist()} met a run-time "
                       f"check")
            error = err
            break
    reason = _check_message(error)
    if not np.isfinite(best_value):
        raise ValueError(f"identify: no finite loss from theta0 = {np.asarray(theta0).tolist()}: {reason}") from None
    k = values.index(best_value)
    failure = (f"identify: {failure or 'a run-time check failed'} ({reason}); returning the best theta found, at "
               f"iteration {k} (loss {best_value:.6g})")
    warnings.warn(failure, RuntimeWarning, stacklevel=3)
    return Identified(best, make_chain(best), jnp.asarray(values), k, failure)


def _check_message(error: Exception) -> str:
    """The message of the run-time check in an ``EquinoxRuntimeError``'s text."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    for line in lines:
        if "EquinoxRuntimeError:" in line:
            return line.split("EquinoxRuntimeError:", 1)[1].strip()
    return lines[0] if lines else type(error).__name__
