"""Kinetic and potential energy from the links' spatial velocities and inertias."""

from __future__ import annotations

import jax.numpy as jnp

from lagrange.planar.model import PlanarChain
from lagrange.planar.recursive.contact import contact_energy, limit_energy
from lagrange.planar.recursive.kinematics import LinkKinematics
from lagrange.planar.recursive.tree import param, prepare


def energy(chain: PlanarChain, q, qd):
    """The kinetic and potential energy, from the links' spatial velocities and inertias.

    Arguments and result as :func:`lagrange.dynamics.energy`'s, for a chain that function has prepared (its
    concrete parameters folded to NumPy arrays); nothing is checked here.
    """
    batch, _, q, qd = prepare(chain, q, qd)
    k = LinkKinematics(chain, q, qd, len(batch))
    # kinetic energy of body i = 1/2 v^T I v with the momentum from the spatial inertia
    t, Fx, Fz = k.momentum(k.w, k.vx, k.vz)
    kin = 0.5 * jnp.sum(k.w * t + k.vx * Fx + k.vz * Fz, axis=0)
    if chain.armature is not None:
        kin = kin + 0.5 * jnp.sum(param(chain.armature, len(batch)) * qd * qd, axis=0)
    if chain.gravity is None:
        pot = jnp.zeros_like(kin)
    else:
        pz = k.topology.path_sum(k.rz)  # height of p_i; the centre of mass is h / m above it
        pot = chain.gravity * jnp.sum(jnp.broadcast_to(k.m * pz + k.hz, q.shape), axis=0)
    if chain.stiffness is not None:  # the joint springs' 1/2 K (q - q_ref)^2
        stretch = q - param(chain.springref, len(batch))
        pot = pot + 0.5 * jnp.sum(param(chain.stiffness, len(batch)) * stretch * stretch, axis=0)
    for extra in (limit_energy(chain, q), contact_energy(chain, k)):  # the penalty springs
        if extra is not None:
            pot = pot + extra
    return kin, pot
