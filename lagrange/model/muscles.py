"""Muscles: force elements along paths through points fixed on the bodies of a tree, driven by activations.

A muscle's path runs through its waypoints ``x_1 .. x_k`` (each fixed on a body, MuJoCo's sites on a spatial tendon);
its length is the polyline's, ``L(q) = sum_i |x_{i+1}(q) - x_i(q)|``. Pulling with the tension ``F >= 0`` it does
the work ``-F dL``, so its generalized force is ``tau = -F dL/dq`` (per velocity: ``dL/dt = dL/dq . qd``). The law of
the tension is the muscle's class: :class:`Muscle`'s is DFlex's, ``F = a * strength`` with the activation ``a`` (the
muscle's control, clamped into ``[0, 1]``), no force-length or force-velocity term; a Hill-type muscle is a subclass
whose :meth:`Muscle.tension` reads ``L`` and ``dL/dt``. How the library computes ``tau``: ``dL/dx_i`` by
differentiating ``L`` with respect to the waypoints (``jax.grad``), then ``J_i(q)^T`` of each waypoint's body, the
same transpose that turns contact forces into generalized forces (:mod:`lagrange.rbda.muscles`); by the chain rule
this is ``-F dL/dq``. A segment whose two ends sit on one rigid link adds to ``L`` and nothing to ``tau``.

The controls of a tree with muscles are its motors' controls, then one activation per muscle, in order
(:attr:`lagrange.Tree.m` counts both).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from lagrange.model.checks import check_array, traced

__all__ = ["Muscle"]


class Muscle(eqx.Module):
    """A muscle along a path of waypoints on bodies, with DFlex's law ``F = a * strength`` (the module docstring).

    Args:
        path: the waypoints in order, each ``(body, (x, y, z))``: the index of a body of the tree and the point in
            that body's frame [m]; at least two.
        strength: the tension at full activation [N], >= 0 (DFlex's SNU humanoid: ``0.36 f0``).
        name: the muscle's name, or ``None``; static.

    Attributes:
        bodies: each waypoint's body; static.
        points: the waypoints in their bodies' frames [m], ``(k, 3)``.
        strength: [N], a 0-d array (differentiable).

    Raises:
        TypeError, ValueError: naming the muscle and the field, for a path of fewer than two waypoints, a body that is
            not an index, a point that is not three finite numbers, a negative strength. Whether the bodies exist is
            checked by :class:`lagrange.Tree`.
    """

    points: Float[Array, "k 3"]
    strength: Float[Array, ""]
    bodies: tuple[int, ...] = eqx.field(static=True)
    name: str | None = eqx.field(static=True)

    length_dependent: ClassVar[bool] = False
    """Whether :meth:`tension` reads the path's length ``L`` (then the library computes it; DFlex's law does not)."""

    velocity_dependent: ClassVar[bool] = False
    """Whether :meth:`tension` reads the path's rate ``dL/dt`` (then the library computes it; DFlex's law does not)."""

    def __init__(self, path, strength: Float[ArrayLike, ""], *, name: str | None = None):
        who = f"Muscle {name!r}" if name else "Muscle"
        if name is not None and (not isinstance(name, str) or not name):
            raise TypeError(f"Muscle.name must be a non-empty string or None, got {name!r}")
        try:
            path = [(b, p) for b, p in path]
        except (TypeError, ValueError) as err:
            raise TypeError(f"{who}.path must be a sequence of (body index, (x, y, z)) waypoints, got {path!r}") \
                from err
        if len(path) < 2:
            raise ValueError(f"{who}.path has {len(path)} waypoint{'s' if len(path) != 1 else ''}; a path needs at "
                             "least two (its length runs from the first to the last)")
        bodies = []
        for i, (b, _) in enumerate(path):
            if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or b < 0:
                raise ValueError(f"{who}.path[{i}]'s body must be a body's index >= 0, got {b!r}")
            bodies.append(int(b))
        self.bodies = tuple(bodies)
        points = [p for _, p in path]
        if traced(*points):
            points = jnp.stack([jnp.asarray(p) for p in points])
        else:
            try:
                points = np.array([np.asarray(p, float) for p in points])
            except (TypeError, ValueError) as err:
                raise TypeError(f"{who}.path's points must be three numbers each, got {points!r}") from err
        self.points = check_array(f"{who}.path's points", points, (len(path), 3))
        self.strength = check_array(f"{who}.strength", strength, nonnegative=True)
        self.name = name

    def tension(self, activation, length, velocity):
        """The tension ``F`` [N] at the clamped ``activation`` in ``[0, 1]``, the path's ``length`` [m] (``None`` unless
        :attr:`length_dependent` or :attr:`velocity_dependent`) and its rate ``velocity`` [m/s] (``None`` unless
        :attr:`velocity_dependent`): DFlex's ``activation * strength``. Arrays of the batch's shape."""
        return activation * self.strength

    @classmethod
    def tensions(cls, muscles, activation, length, velocity):
        """The tensions of several muscles of this class at once: the arguments' rows (their leading axis) are the
        muscles', the rest of each the batch. :class:`Muscle`'s: ``activation`` times the strengths, one product (a
        stack of 152 separate products once cost DFlex's SNU humanoid a tenfold slower step on a CPU). A subclass that
        overrides :meth:`tension` and not this gets one muscle at a time."""
        strength = [m.strength for m in muscles]
        strength = jnp.stack(strength) if traced(*strength) else np.stack([np.asarray(x) for x in strength])
        return activation * jnp.asarray(strength, activation.dtype).reshape((-1,) + (1,) * (activation.ndim - 1))

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "tension" in cls.__dict__ and "tensions" not in cls.__dict__:
            cls.tensions = classmethod(_one_at_a_time)


def _one_at_a_time(cls, muscles, activation, length, velocity):
    """:meth:`Muscle.tensions` by each muscle's own :meth:`Muscle.tension`."""
    return jnp.stack([m.tension(activation[i], None if length is None else length[i],
                                None if velocity is None else velocity[i]) for i, m in enumerate(muscles)])
