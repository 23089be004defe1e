"""A catalogue of chains, with defaults matching the CE-APG paper's environments.

Every physical parameter is a keyword. Lengths the paper does not state are 1 m, and link
inertias are thin rods (``m l^2 / 12``) unless given.

=================  =====================================  ==========================
system             coordinates ``q``                       actuation
=================  =====================================  ==========================
pendulum           (theta,)                               torque, gear 1
cartpole           (x, theta)                             cart force, gear 100
double_cartpole    (x, theta1, theta2)                    cart force, gear 1000
acrobot            (theta1, theta2)                       elbow torque, gear 25
n_link_pendulum    (theta1, ..., thetan)                  none unless ``gear`` given
=================  =====================================  ==========================

Angles are relative joint angles; ``q = 0`` hangs straight down, so a pole is upright at pi.
"""

from __future__ import annotations

from lagrange.chain import Chain, Link


def pendulum(*, mass=1.0, length=1.0, com=None, inertia=None, damping=0.0, gear=1.0, gravity=9.81) -> Chain:
    """A single revolute link hanging from the origin."""
    return Chain([Link("revolute", mass, length, com, inertia, damping=damping, gear=gear)], gravity=gravity)


def cartpole(
    *, cart_mass=10.47, pole_mass=5.02, pole_length=1.0, pole_inertia=None, damping=0.0, gear=100.0, gravity=9.81
) -> Chain:
    """A cart on the x axis (prismatic, actuated) carrying one pole (revolute, passive)."""
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_mass, pole_length, inertia=pole_inertia),
        ],
        gravity=gravity,
    )


def double_cartpole(
    *,
    cart_mass=10.47,
    pole_masses=(5.02, 5.02),
    pole_lengths=(1.0, 1.0),
    damping=0.0,
    gear=1000.0,
    gravity=9.81,
) -> Chain:
    """A cart on the x axis (actuated) carrying two poles in series (passive)."""
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_masses[0], pole_lengths[0]),
            Link("revolute", pole_masses[1], pole_lengths[1]),
        ],
        gravity=gravity,
    )


def acrobot(*, masses=(2.5, 2.5), lengths=(1.0, 1.0), inertias=(None, None), damping=0.0, gear=25.0, gravity=9.81) -> Chain:
    """Two revolute links; the shoulder is passive and the elbow actuated."""
    return Chain(
        [
            Link("revolute", masses[0], lengths[0], inertia=inertias[0], damping=damping),
            Link("revolute", masses[1], lengths[1], inertia=inertias[1], damping=damping, gear=gear),
        ],
        gravity=gravity,
    )


def n_link_pendulum(n: int, *, mass=1.0, length=1.0, damping=0.0, gear=None, gravity=9.81) -> Chain:
    """``n`` identical revolute links in series (``gear`` actuates every joint)."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    return Chain([Link("revolute", mass, length, damping=damping, gear=gear) for _ in range(n)], gravity=gravity)
