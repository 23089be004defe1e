"""A catalogue of chains, with defaults matching the CE-APG paper's environments.

Every physical parameter is a keyword. Lengths the paper does not state are 1 m, and link
inertias are thin rods (``m l^2 / 12``) unless given.

``BRAX_V1[name]`` holds the keywords that rebuild the bodies the CE-APG authors simulated, as their Brax v1
configs describe them (acrobot: capsules 1 m long with the hinges 0.45 m either side of the centre; carts: poles
0.698 m long hinged 0.3 m from the centre). Those configs give masses but no inertias, and Brax v1 then sets
every body's inertia to (1, 1, 1) kg m^2 (``validate_config``), about five times a 1 m, 2.5 kg rod's
(0.21 kg m^2) and 2.4 times a 1 m, 5.02 kg pole's: heavy, slow links no physical rod of that mass and length
has. ``lagrange.tasks.make_task(name, bodies="brax_v1")`` builds a task on them.

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
    *, cart_mass=10.47, pole_mass=5.02, pole_length=1.0, pole_com=None, pole_inertia=None, damping=0.0, gear=100.0,
    gravity=9.81,
) -> Chain:
    """A cart on the x axis (prismatic, actuated) carrying one pole (revolute, passive)."""
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_mass, pole_length, com=pole_com, inertia=pole_inertia),
        ],
        gravity=gravity,
    )


def double_cartpole(
    *,
    cart_mass=10.47,
    pole_masses=(5.02, 5.02),
    pole_lengths=(1.0, 1.0),
    pole_coms=(None, None),
    pole_inertias=(None, None),
    damping=0.0,
    gear=1000.0,
    gravity=9.81,
) -> Chain:
    """A cart on the x axis (actuated) carrying two poles in series (passive)."""
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_masses[0], pole_lengths[0], com=pole_coms[0], inertia=pole_inertias[0]),
            Link("revolute", pole_masses[1], pole_lengths[1], com=pole_coms[1], inertia=pole_inertias[1]),
        ],
        gravity=gravity,
    )


def acrobot(*, masses=(2.5, 2.5), lengths=(1.0, 1.0), coms=(None, None), inertias=(None, None), damping=0.0,
            gear=25.0, gravity=9.81) -> Chain:
    """Two revolute links; the shoulder is passive and the elbow actuated."""
    return Chain(
        [
            Link("revolute", masses[0], lengths[0], com=coms[0], inertia=inertias[0], damping=damping),
            Link("revolute", masses[1], lengths[1], com=coms[1], inertia=inertias[1], damping=damping, gear=gear),
        ],
        gravity=gravity,
    )


def n_link_pendulum(n: int, *, mass=1.0, length=1.0, damping=0.0, gear=None, gravity=9.81) -> Chain:
    """``n`` identical revolute links in series (``gear`` actuates every joint)."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    return Chain([Link("revolute", mass, length, damping=damping, gear=gear) for _ in range(n)], gravity=gravity)


BRAX_V1 = {
    "acrobot": dict(masses=(2.5, 2.5), lengths=(0.9, 0.9), coms=(0.45, 0.45), inertias=(1.0, 1.0)),
    "cartpole": dict(cart_mass=10.471975, pole_mass=5.0185914, pole_length=0.6, pole_com=0.3, pole_inertia=1.0),
    "double_cartpole": dict(cart_mass=10.471975, pole_masses=(5.0185914, 5.0185914), pole_lengths=(0.6, 0.6),
                            pole_coms=(0.3, 0.3), pole_inertias=(1.0, 1.0)),
}
"""The CE-APG authors' bodies, from their Brax v1 configs: the keywords of :func:`acrobot`, :func:`cartpole` and
:func:`double_cartpole` that build them. Hinge offsets from each capsule's centre give ``com`` and the hinge-to-hinge
``length``; no inertia is given there, so Brax v1's default of 1 kg m^2 applies. The cartpole's pole has no second
hinge; its length (0.6 m) only places the drawn tip. ``lagrange.tasks.make_task(name, bodies="brax_v1")`` uses them."""
