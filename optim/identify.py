"""System identification: fit a chain's physical parameters to observed trajectories through ``lagrange.simulate``.

:func:`identify` minimises the squared error between simulated and observed windows of a trajectory (each window
restarted from its observed first state, so the error does not compound over a long horizon) over a parameter vector
``theta`` that ``make_chain(theta)`` turns into a :class:`lagrange.Chain`: L-BFGS (``optax.lbfgs``, with its zoom line
search) on the gradient ``jax.grad`` takes through the solver's steps, all iterations in one compiled ``lax.scan``.
Any parameter a chain has can be identified this way (masses, lengths, inertias, damping, gears, gravity), and any
parametrisation (a log scale keeps a mass positive; a density ties a link's inertia to its mass).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import optax
from jaxtyping import Array, ArrayLike, Float

import lagrange as lg
from lagrange.chain import Chain

__all__ = ["Identified", "identify"]


class Identified(NamedTuple):
    """What :func:`identify` returns: the fitted ``theta``, its ``chain``, and the loss before every iteration and
    after the last (``losses``, shape ``(iterations + 1,)``)."""

    theta: Float[Array, " p"]
    chain: Chain
    losses: Float[Array, " iterations+1"]


def identify(
    make_chain: Callable[[Float[Array, " p"]], Chain],
    theta0: Float[ArrayLike, " p"],
    states: Float[ArrayLike, "W T+1 2n"],
    controls: Float[ArrayLike, "W T m"] | None,
    dt: float,
    solver=lg.RK4(),
    *,
    iterations: int = 100,
) -> Identified:
    """Fit ``theta`` so that ``make_chain(theta)`` reproduces observed windows of trajectories.

    Args:
        make_chain: ``theta -> Chain``, differentiable in ``theta``.
        theta0: the starting guess, shape ``(p,)``.
        states: ``W`` observed windows of ``T`` steps, each row ``(q, qd)``: shape ``(W, T + 1, 2 n)``.
        controls: the controls held over each step, ``(W, T, m)``; ``None`` for a chain without actuators.
        dt: the step [s], > 0; ``solver`` the integrator that produced (or models) the data.
        iterations: L-BFGS iterations, >= 1.

    The loss is the mean squared error of the simulated windows against ``states[:, 1:]``, every coordinate and
    velocity divided by the standard deviation of its change per step in the data (so that positions and velocities,
    metres and radians weigh alike).

    Raises:
        ValueError: for shapes that do not match the chain, ``dt <= 0`` or ``iterations < 1``.
    """
    theta0 = jnp.asarray(theta0)
    states = jnp.asarray(states)
    chain0 = make_chain(theta0)
    n, m = chain0.n, chain0.m
    if states.ndim != 3 or states.shape[-1] != 2 * n or states.shape[1] < 2:
        raise ValueError(f"identify: states must have shape (windows, T + 1 >= 2, 2 n = {2 * n}), got {states.shape}")
    windows, steps = states.shape[0], states.shape[1] - 1
    if m:
        if controls is None or jnp.shape(controls) != (windows, steps, m):
            raise ValueError(f"identify: controls must have shape (windows, T, m) = {(windows, steps, m)}, got "
                             f"{None if controls is None else jnp.shape(controls)}")
        controls = jnp.asarray(controls, states.dtype)
    if not float(dt) > 0:
        raise ValueError(f"identify: dt must be > 0 seconds, got {dt!r}")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"identify: iterations must be an integer >= 1, got {iterations!r}")
    target = states[:, 1:]
    scale = jnp.std(target - states[:, :-1], axis=(0, 1))
    scale = jnp.where(scale > 0, scale, 1.0)

    def loss(theta):
        chain = make_chain(theta)

        def window(x, u):
            tr = lg.simulate(chain, x[0, :n], x[0, n:], u, dt, solver, steps=steps)
            return jnp.concatenate([tr.q[1:], tr.qd[1:]], axis=-1)

        sim = jax.vmap(window)(states, controls) if m else jax.vmap(lambda x: window(x, None))(states)
        return jnp.mean(((sim - target) / scale) ** 2)

    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss)

    def step(carry, _):
        theta, state = carry
        value, grad = value_and_grad(theta, state=state)
        updates, state = opt.update(grad, state, theta, value=value, grad=grad, value_fn=loss)
        return (optax.apply_updates(theta, updates), state), value

    @jax.jit
    def fit(theta):
        (theta, _), values = jax.lax.scan(step, (theta, opt.init(theta)), None, length=iterations)
        return theta, jnp.append(values, loss(theta))

    theta, losses = fit(theta0)
    return Identified(theta, make_chain(theta), losses)
