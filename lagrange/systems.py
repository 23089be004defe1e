"""A catalogue of chains, with defaults matching the CE-APG paper's environments.

Every physical parameter is a keyword. Lengths the paper does not state are 1 m, and link
inertias are thin rods (``m l^2 / 12``) unless given.

``BRAX_V1[name]`` holds the keywords that rebuild the bodies the CE-APG authors simulated, as their Brax v1
configs describe them (acrobot: capsules 1 m long with the hinges 0.45 m either side of the centre; carts: poles
0.698 m long hinged 0.3 m from the centre). Those configs give masses but no inertias, and Brax v1 then sets
every body's inertia to (1, 1, 1) kg m^2 (``validate_config``), about five times a 1 m, 2.5 kg rod's
(0.21 kg m^2) and 2.4 times a 1 m, 5.02 kg pole's: heavy, slow links no physical rod of that mass and length
has. ``lagrange.tasks.Acrobot.brax_v1()`` (likewise ``Cartpole``, ``DoubleCartpole``) builds a task on them.

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

from jaxtyping import ArrayLike, Float

from lagrange.chain import Chain, Link

Scalar = Float[ArrayLike, ""]
"""A real scalar: a Python number or a 0-d array (traced values included, to differentiate a system)."""


def pendulum(
    *,
    mass: Scalar = 1.0,
    length: Scalar = 1.0,
    com: Scalar | None = None,
    inertia: Scalar | None = None,
    damping: Scalar = 0.0,
    gear: Scalar | None = 1.0,
    gravity: Scalar = 9.81,
) -> Chain:
    """A single revolute link hanging from the origin.

    Args:
        mass: the link's mass [kg].
        length: its length [m].
        com: its centre of mass's distance from the joint [m]; ``None``: ``length / 2``.
        inertia: its moment of inertia about the centre of mass [kg m^2]; ``None``: a thin rod's.
        damping: joint damping [N m s/rad].
        gear: the torque's gear (torque ``gear * u`` [N m]); ``None`` leaves the joint passive.
        gravity: gravitational acceleration [m/s^2].

    Returns:
        The :class:`~lagrange.chain.Chain`: ``q = (theta,)`` [rad], ``u`` of shape ``(1,)`` (``(0,)`` with
        ``gear=None``).
    """
    return Chain([Link("revolute", mass, length, com, inertia, damping=damping, gear=gear)], gravity=gravity)


def cartpole(
    *,
    cart_mass: Scalar = 10.47,
    pole_mass: Scalar = 5.02,
    pole_length: Scalar = 1.0,
    pole_com: Scalar | None = None,
    pole_inertia: Scalar | None = None,
    damping: Scalar = 0.0,
    gear: Scalar = 100.0,
    gravity: Scalar = 9.81,
) -> Chain:
    """A cart on the x axis (prismatic, actuated) carrying one pole (revolute, passive).

    Args:
        cart_mass: the cart's mass [kg].
        pole_mass: the pole's mass [kg].
        pole_length: the pole's length [m].
        pole_com: the pole's centre of mass's distance from its hinge [m]; ``None``: ``pole_length / 2``.
        pole_inertia: the pole's moment of inertia about its centre of mass [kg m^2]; ``None``: a thin rod's.
        damping: the cart's damping [N s/m].
        gear: the cart force's gear (force ``gear * u`` [N]).
        gravity: gravitational acceleration [m/s^2].

    Returns:
        The :class:`~lagrange.chain.Chain`: ``q = (x, theta)`` [m, rad], the pole upright at ``theta = pi``; ``u`` of
        shape ``(1,)``.
    """
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_mass, pole_length, com=pole_com, inertia=pole_inertia),
        ],
        gravity=gravity,
    )


def double_cartpole(
    *,
    cart_mass: Scalar = 10.47,
    pole_masses: tuple[Scalar, Scalar] = (5.02, 5.02),
    pole_lengths: tuple[Scalar, Scalar] = (1.0, 1.0),
    pole_coms: tuple[Scalar | None, Scalar | None] = (None, None),
    pole_inertias: tuple[Scalar | None, Scalar | None] = (None, None),
    damping: Scalar = 0.0,
    gear: Scalar = 1000.0,
    gravity: Scalar = 9.81,
) -> Chain:
    """A cart on the x axis (actuated) carrying two poles in series (passive).

    Args:
        cart_mass: the cart's mass [kg].
        pole_masses: the poles' masses [kg].
        pole_lengths: the poles' lengths [m].
        pole_coms: each pole's centre of mass's distance from its hinge [m]; ``None``: half its length.
        pole_inertias: each pole's moment of inertia about its centre of mass [kg m^2]; ``None``: a thin rod's.
        damping: the cart's damping [N s/m].
        gear: the cart force's gear (force ``gear * u`` [N]).
        gravity: gravitational acceleration [m/s^2].

    Returns:
        The :class:`~lagrange.chain.Chain`: ``q = (x, theta1, theta2)`` [m, rad, rad], upright at
        ``(x, pi, 0)``; ``u`` of shape ``(1,)``.
    """
    return Chain(
        [
            Link("prismatic", cart_mass, 0.0, com=0.0, inertia=0.0, damping=damping, gear=gear),
            Link("revolute", pole_masses[0], pole_lengths[0], com=pole_coms[0], inertia=pole_inertias[0]),
            Link("revolute", pole_masses[1], pole_lengths[1], com=pole_coms[1], inertia=pole_inertias[1]),
        ],
        gravity=gravity,
    )


def acrobot(
    *,
    masses: tuple[Scalar, Scalar] = (2.5, 2.5),
    lengths: tuple[Scalar, Scalar] = (1.0, 1.0),
    coms: tuple[Scalar | None, Scalar | None] = (None, None),
    inertias: tuple[Scalar | None, Scalar | None] = (None, None),
    damping: Scalar = 0.0,
    gear: Scalar = 25.0,
    gravity: Scalar = 9.81,
) -> Chain:
    """Two revolute links; the shoulder is passive and the elbow actuated.

    Args:
        masses: the links' masses [kg].
        lengths: the links' lengths [m].
        coms: each link's centre of mass's distance from its joint [m]; ``None``: half its length.
        inertias: each link's moment of inertia about its centre of mass [kg m^2]; ``None``: a thin rod's.
        damping: both joints' damping [N m s/rad].
        gear: the elbow torque's gear (torque ``gear * u`` [N m]).
        gravity: gravitational acceleration [m/s^2].

    Returns:
        The :class:`~lagrange.chain.Chain`: ``q = (theta1, theta2)`` [rad], upright at ``(pi, 0)``; ``u`` of shape
        ``(1,)``.
    """
    return Chain(
        [
            Link("revolute", masses[0], lengths[0], com=coms[0], inertia=inertias[0], damping=damping),
            Link("revolute", masses[1], lengths[1], com=coms[1], inertia=inertias[1], damping=damping, gear=gear),
        ],
        gravity=gravity,
    )


def n_link_pendulum(
    n: int,
    *,
    mass: Scalar = 1.0,
    length: Scalar = 1.0,
    damping: Scalar = 0.0,
    gear: Scalar | None = None,
    gravity: Scalar = 9.81,
) -> Chain:
    """``n`` identical revolute links in series, thin rods.

    Args:
        n: the number of links, an integer >= 1.
        mass: each link's mass [kg].
        length: each link's length [m].
        damping: each joint's damping [N m s/rad].
        gear: actuates every joint (torques ``gear * u`` [N m]); ``None`` leaves them passive.
        gravity: gravitational acceleration [m/s^2].

    Returns:
        The :class:`~lagrange.chain.Chain`: ``q = (theta1, ..., thetan)`` [rad]; ``u`` of shape ``(n,)``, or
        ``(0,)`` with ``gear=None``.

    Raises:
        ValueError: if ``n`` is not an integer >= 1.
    """
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
hinge; its length (0.6 m) only places the drawn tip. ``lagrange.tasks.Acrobot.brax_v1()`` and its siblings use them."""
