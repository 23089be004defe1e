"""Planar serial chains: links, joints and their physical parameters.

Conventions (see also the docs' "Conventions" page):

- The chain lives in the vertical x-z plane; gravity points along -z.
- Every body frame has an origin ``p`` and an angle ``phi``. The link direction is
  ``d(phi) = (sin phi, -cos phi)`` and its normal ``e(phi) = (cos phi, sin phi)``. The base frame
  has ``p = 0`` and ``phi = 0``: links hang straight down and ``e`` points along +x.
- Link ``i`` starts at the tip of link ``i-1``: ``p_i = p_{i-1} + l_{i-1} d(phi_{i-1})``.
- ``joint="revolute"``: ``phi_i = phi_{i-1} + q_i``. ``joint="prismatic"``: ``phi_i = phi_{i-1}``
  and the frame slides by ``q_i`` along ``e(phi_{i-1} + axis)``; a prismatic base joint with
  ``axis=0`` is a cart on the x axis.
- The centre of mass is at ``p_i + com d(phi_i)`` (default ``com = length / 2``); ``inertia`` is
  the moment of inertia about the centre of mass, normal to the plane (default
  ``mass length^2 / 12``, a thin rod). ``damping`` is viscous (generalized force
  ``-damping qd_i``), ``armature`` is added to ``M_ii``, and ``gear`` makes the joint actuated
  (generalized force ``gear u_k``, ``k`` counting actuated joints in order).

Structure is static: the number of links, the joint kinds, the prismatic axes, which joints
are actuated and which optional terms exist. A term given as exactly zero (no damping, no
armature, zero gravity) is structurally absent and costs nothing in the compiled program; give
it a non-zero value if you want to differentiate with respect to it.
"""

from __future__ import annotations

import math
from typing import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

JOINTS = ("revolute", "prismatic")
"""The joint kinds a :class:`Link` may have."""


def _concrete(x):
    """The value of ``x`` as a NumPy array, or ``None`` if it is traced (not known yet)."""
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(f"expected a real number, got {x!r} of type {type(x).__name__}") from err


def _check_scalar(name: str, value, *, positive: bool = False, nonnegative: bool = False, optional: bool = False):
    if value is None:
        if optional:
            return None
        raise TypeError(f"Link.{name} must be a real number, got None")
    if isinstance(value, (bool, np.bool_)) or isinstance(value, str):
        raise TypeError(f"Link.{name} must be a real number, got {value!r}")
    try:
        c = _concrete(value)
    except TypeError as err:
        raise TypeError(f"Link.{name} must be a real number, got {value!r}") from err
    if c is None:
        return value
    if c.shape != ():
        raise ValueError(f"Link.{name} must be a scalar, got an array of shape {c.shape}")
    v = float(c)
    if not math.isfinite(v):
        raise ValueError(f"Link.{name} must be finite, got {v}")
    if positive and v <= 0:
        raise ValueError(f"Link.{name} must be > 0, got {v}")
    if nonnegative and v < 0:
        raise ValueError(f"Link.{name} must be >= 0, got {v}")
    return value


class Link(eqx.Module):
    """One link of a planar chain and the joint that connects it to its parent.

    Args:
        joint: ``"revolute"`` or ``"prismatic"``.
        mass: link mass [kg], >= 0.
        length: distance from this joint to the next one [m], >= 0.
        com: distance from the joint to the centre of mass along the link [m]; default ``length/2``.
        inertia: moment of inertia about the centre of mass [kg m^2], >= 0; default ``mass length^2/12``.
        axis: for a prismatic joint, the slide direction's angle relative to the parent's normal
            ``e`` [rad]; static.
        damping: viscous joint damping [N s/m or N m s/rad], >= 0.
        armature: rotor inertia added to the joint's diagonal of M, >= 0.
        gear: if given (> 0), the joint is actuated with generalized force ``gear * u``; ``None``
            (the default) leaves it passive. To reverse a motor, negate its control.
    """

    joint: str = eqx.field(static=True)
    mass: object
    length: object = 0.0
    com: object = None
    inertia: object = None
    axis: float = eqx.field(static=True, default=0.0)
    damping: object = 0.0
    armature: object = 0.0
    gear: object = None

    def __init__(self, joint, mass, length=0.0, com=None, inertia=None, axis=0.0, damping=0.0, armature=0.0, gear=None):
        if isinstance(joint, np.str_):
            joint = str(joint)
        if not isinstance(joint, str) or joint not in JOINTS:
            raise ValueError(f"Link.joint must be one of {JOINTS}, got {joint!r}")
        _check_scalar("axis", axis)
        self.joint = joint
        self.mass = mass
        self.length = length
        self.com = com
        self.inertia = inertia
        self.axis = float(axis)
        self.damping = damping
        self.armature = armature
        self.gear = gear

    def __check_init__(self):
        if not isinstance(self.joint, str) or self.joint not in JOINTS:
            raise ValueError(f"Link.joint must be one of {JOINTS}, got {self.joint!r}")
        _check_scalar("mass", self.mass, nonnegative=True)
        _check_scalar("length", self.length, nonnegative=True)
        _check_scalar("com", self.com, optional=True)
        _check_scalar("inertia", self.inertia, nonnegative=True, optional=True)
        _check_scalar("axis", self.axis)
        _check_scalar("damping", self.damping, nonnegative=True)
        _check_scalar("armature", self.armature, nonnegative=True)
        _check_scalar("gear", self.gear, positive=True, optional=True)


def _is_zero(x) -> bool:
    c = _concrete(x)
    return c is not None and float(c) == 0.0


class Chain(eqx.Module):
    """An immutable planar serial chain.

    Physical parameters are array leaves of shape ``(n,)`` (``gear``: ``(m,)``), so
    ``jax.grad``/``eqx.filter_grad`` with respect to masses, lengths, inertias, damping and
    gravity works. Structure is static (see the module docstring).

    Args:
        links: a non-empty sequence of :class:`Link`.
        gravity: gravitational acceleration [m/s^2] along -z; finite.
    """

    mass: jax.Array
    length: jax.Array
    com: jax.Array
    inertia: jax.Array
    damping: jax.Array | None
    armature: jax.Array | None
    gear: jax.Array | None
    gravity: jax.Array | None
    joints: tuple[str, ...] = eqx.field(static=True)
    axes: tuple[float, ...] = eqx.field(static=True)
    actuated: tuple[int, ...] = eqx.field(static=True)
    damped: tuple[int, ...] = eqx.field(static=True)
    armatured: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, links: Sequence[Link], gravity=9.81):
        if isinstance(links, Link):
            raise TypeError("Chain.links must be a sequence of Link, got a single Link; wrap it in a list")
        links = tuple(links)
        if len(links) == 0:
            raise ValueError("Chain.links must contain at least one Link, got none")
        for i, link in enumerate(links):
            if not isinstance(link, Link):
                raise TypeError(f"Chain.links[{i}] must be a lagrange.chain.Link, got {type(link).__name__}")
        if gravity is None or isinstance(gravity, (bool, str)):
            raise TypeError(f"Chain.gravity must be a real number (use 0.0 for none), got {gravity!r}")
        g = _concrete(gravity)
        if g is not None:
            if g.shape != ():
                raise ValueError(f"Chain.gravity must be a scalar, got shape {g.shape}")
            if not math.isfinite(float(g)):
                raise ValueError(f"Chain.gravity must be finite, got {float(g)}")

        dtype = jax.dtypes.canonicalize_dtype(float)

        def stack(values):
            return jnp.stack([jnp.asarray(v, dtype=dtype) for v in values])

        self.mass = stack([lk.mass for lk in links])
        self.length = stack([lk.length for lk in links])
        self.com = stack([lk.length / 2 if lk.com is None else lk.com for lk in links])
        self.inertia = stack(
            [lk.mass * lk.length**2 / 12 if lk.inertia is None else lk.inertia for lk in links]
        )
        self.joints = tuple(lk.joint for lk in links)
        self.axes = tuple(float(lk.axis) for lk in links)
        self.actuated = tuple(i for i, lk in enumerate(links) if lk.gear is not None)
        self.damped = tuple(i for i, lk in enumerate(links) if not _is_zero(lk.damping))
        self.armatured = tuple(i for i, lk in enumerate(links) if not _is_zero(lk.armature))
        self.damping = stack([lk.damping for lk in links]) if self.damped else None
        self.armature = stack([lk.armature for lk in links]) if self.armatured else None
        self.gear = stack([links[i].gear for i in self.actuated]) if self.actuated else None
        self.gravity = None if _is_zero(gravity) else jnp.asarray(gravity, dtype=dtype)
        _check_not_singular(self)

    @property
    def n(self) -> int:
        """Number of generalized coordinates (links)."""
        return len(self.joints)

    @property
    def m(self) -> int:
        """Number of actuated joints (controls)."""
        return len(self.actuated)

    def links(self) -> tuple[Link, ...]:
        """The chain as a tuple of :class:`Link` (for editing and re-building)."""
        out = []
        k = {j: i for i, j in enumerate(self.actuated)}
        for i, joint in enumerate(self.joints):
            out.append(
                Link(
                    joint,
                    self.mass[i],
                    self.length[i],
                    self.com[i],
                    self.inertia[i],
                    axis=self.axes[i],
                    damping=0.0 if self.damping is None else self.damping[i],
                    armature=0.0 if self.armature is None else self.armature[i],
                    gear=None if i not in k else self.gear[k[i]],
                )
            )
        return tuple(out)


def _check_not_singular(chain: Chain) -> None:
    """Raise if the mass matrix is singular (checked at a few configurations, if concrete)."""
    leaves = [chain.mass, chain.length, chain.com, chain.inertia, chain.armature]
    if any(isinstance(x, jax.core.Tracer) for x in leaves if x is not None):
        return
    from lagrange.dynamics import mass_matrix  # local: dynamics imports chain

    rng = np.random.default_rng(0)
    qs = [np.zeros(chain.n)] + [rng.uniform(-3, 3, chain.n) for _ in range(2)]
    with jax.ensure_compile_time_eval():
        for q in qs:
            M = np.asarray(mass_matrix(chain, jnp.asarray(q)))
            w = np.linalg.eigvalsh(M)
            scale = max(float(np.max(np.abs(w))), 1e-300)
            if not np.all(np.isfinite(w)) or w[0] <= 1e-12 * scale:
                bad = [
                    i
                    for i in range(chain.n)
                    if float(chain.mass[i]) == 0.0 and float(chain.inertia[i]) == 0.0
                ]
                hint = f" (links {bad} have zero mass and zero inertia)" if bad else ""
                raise ValueError(
                    "Chain has a singular mass matrix: every coordinate must move some mass, "
                    f"inertia or armature{hint}; smallest eigenvalue {w[0]:.3g} at q={q.tolist()}"
                )
