"""Helpers shared by several test modules (the oracles they compare against live in ``benchmarks/oracles/``).

- ``assert_close``, ``states``, ``per_state`` and ``random_chain``: random chains and states for the checks of the
  equations of motion (``tests/lagrange/test_dynamics.py``, ``planar/test_recursive.py``, ``test_systems.py``).
- ``seeded_chain``, ``mujoco_model``, ``mujoco_batch_rollout``, ``random_problem``, ``rel``, ``SYSTEMS`` and ``CHAINS``:
  the chains exported to MuJoCo C and Brax and their rollouts (``tests/lagrange/test_against_mujoco.py``,
  ``test_against_brax.py`` and ``tests/lagrange/interop/test_mjcf.py``). Errors there are

      rel(a, b) = max|a - b| / max(1, max|b|)

  (the largest error relative to the reference's largest entry, absolute below 1).
- ``param_count``, ``pendulum_swingup`` (a small task a trainer learns in seconds), ``tiny_acrobot``, ``tiny_gru``,
  ``tiny_mlp``, ``tiny_ce_apg_config``, ``small_problem`` (a small run of each algorithm: the ``short_run`` fixture
  of ``tests/optim/conftest.py``), ``states_equal`` and ``ROOT`` (the repository, the working directory of the
  tests that start a fresh interpreter): ``tests/policies/`` and ``tests/optim/``.
"""

from __future__ import annotations

import math
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrange as lg
from lagrange.chain import Chain, Link
from lagrange.planar.lower import lower as planar
from lagrange.interop.mjcf import to_mjcf


REL = 1e-12  # M, bias and gravity forces in float64: see tests/lagrange/test_dynamics.py's docstring


def assert_close(actual, expected, rel=REL, what=""):
    """max |actual - expected| <= rel * max(1, max |expected|)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape, (what, actual.shape, expected.shape)
    scale = max(1.0, float(np.max(np.abs(expected))))
    err = float(np.max(np.abs(actual - expected)))
    assert err <= rel * scale, f"{what}: max error {err:.3g} > {rel:.1e} x scale {scale:.3g}"


def states(rng, n, k=16):
    """k random states with angles over the whole circle and velocities up to 3 rad/s."""
    q = jnp.asarray(rng.uniform(-np.pi, np.pi, (k, n)))
    qd = jnp.asarray(rng.uniform(-3.0, 3.0, (k, n)))
    return q, qd


def per_state(f, chain, *xs):
    """Evaluate a single-state function at each of a stack of states (no reliance on batch dims)."""
    return jax.jit(jax.vmap(lambda *x: f(chain, *x)))(*xs)


def random_chain(rng, n, damped=0.5, *, cart=False, gravity=None, frames=False):
    """A random chain of n links: mixed joints, random prismatic axes, com, inertia, and
    damping/armature/gear present on random subsets of the joints. ``cart``: link 0 is a prismatic
    cart on the x axis. ``gravity``: fixed, or None for one drawn by ``n`` (``tests/lagrange/planar/test_recursive.py``
    fixes it by ``n``). ``frames``: every link also gets a frame offset (random, or exactly pi) and a centre of
    mass off its line."""
    if frames:
        chain = random_chain(rng, n, damped, cart=cart, gravity=gravity)
        links = [
            Link(
                lk.joint, lk.mass, lk.length, lk.com, lk.inertia, axis=lk.axis, damping=lk.damping,
                armature=lk.armature, gear=lk.gear, com_normal=float(rng.uniform(-0.4, 0.4)),
                offset=float(rng.choice([np.pi, rng.uniform(-np.pi, np.pi)])),
            )
            for lk in chain.links()
        ]
        g = planar(chain).gravity
        return Chain(links, gravity=9.81 if g is None else g)
    links = []
    for i in range(n):
        base_cart = cart and i == 0
        prismatic = base_cart or rng.random() < 0.35
        axis = float(rng.uniform(-np.pi, np.pi)) if prismatic and not base_cart and rng.random() < 0.7 else 0.0
        length = float(rng.uniform(0.2, 1.5))
        links.append(
            Link(
                "prismatic" if prismatic else "revolute",
                float(rng.uniform(0.3, 3.0)),
                length,
                com=float(rng.uniform(0.0, length)) if rng.random() < 0.5 else None,
                inertia=float(rng.uniform(0.01, 0.5)) if rng.random() < 0.5 else None,
                axis=axis,
                damping=float(rng.uniform(0.05, 1.0)) if rng.random() < damped else 0.0,
                armature=float(rng.uniform(0.01, 0.2)) if rng.random() < 0.5 else 0.0,
                gear=float(rng.uniform(0.5, 5.0)) if rng.random() < 0.5 else None,
            )
        )
    if gravity is None:
        gravity = (0.0, float(rng.uniform(1.0, 20.0)), 9.81)[n % 3] if damped < 1 else 9.81
    return Chain(links, gravity=gravity)


# --------------------------------------------------------------- MuJoCo C and Brax on the exported model

TRAJECTORY = 1e-9  # 500-step trajectories (see tests/lagrange/test_against_mujoco.py's docstring)


# Catalogue systems with their physics step from the paper (control dt / substeps).
SYSTEMS = {
    "pendulum": (lambda: lg.systems.pendulum(damping=0.1), 0.01),
    "cartpole": (lg.systems.cartpole, 0.04 / 8),
    "double_cartpole": (lg.systems.double_cartpole, 0.01 / 12),
    "acrobot": (lg.systems.acrobot, 0.01 / 4),
}


def rel(a, b) -> float:
    """max|a - b| / max(1, max|b|)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def seeded_chain(seed: int, *, slide_below_hinge: bool = True) -> Chain:
    """A seeded random chain of 2-8 links with mixed joints, damping, armature and gears.

    With ``slide_below_hinge=False`` no prismatic joint follows a revolute one (the chains that
    Brax 0.14 simulates correctly).
    """
    rng = np.random.default_rng(seed)
    n = 2 + seed % 7  # seeds 0..6 cover every size from 2 to 8
    specs = []
    seen_revolute = False
    for i in range(n):
        prismatic = rng.random() < (0.5 if i == 0 else 0.3)
        if prismatic and seen_revolute and not slide_below_hinge:
            prismatic = False
        seen_revolute |= not prismatic
        length = float(rng.uniform(0.2, 1.0)) if (not prismatic or rng.random() < 0.5) else 0.0
        specs.append(
            dict(
                joint="prismatic" if prismatic else "revolute",
                mass=float(rng.uniform(0.3, 3.0)),
                length=length,
                com=float(rng.uniform(0.0, 1.0)) * length,
                inertia=float(rng.uniform(0.01, 0.3)) if rng.random() < 0.5 else None,
                axis=float(rng.uniform(-math.pi, math.pi)) if prismatic and rng.random() < 0.5 else 0.0,
                damping=float(rng.uniform(0.05, 1.0)) if rng.random() < 0.5 else 0.0,
                armature=float(rng.uniform(0.01, 0.3)) if rng.random() < 0.4 else 0.0,
                gear=float(abs(rng.choice([-1, 1]) * rng.uniform(0.5, 5.0))) if rng.random() < 0.6 else None,
            )
        )
    if all(spec["gear"] is None for spec in specs):
        specs[0]["gear"] = 1.0
    links = [Link(**spec) for spec in specs]
    return Chain(links, gravity=9.81)


def rebuilt(chain: Chain, *, gravity=None, **per_link) -> Chain:
    """``chain`` built again from its links (:meth:`lagrange.chain.Chain.links`) with some of their parameters
    replaced: ``per_link`` arrays ``(n,)`` (``mass=``, ``length=``, ``inertia=``, ``damping=``, ...), entry ``i`` for
    link ``i``, and ``gravity``; the values may be traced (a derivative with respect to them through the builder, as the
    old chain's parameter arrays were differentiated)."""
    import dataclasses

    links = [dataclasses.replace(lk, **{k: v[i] for k, v in per_link.items()}) for i, lk in enumerate(chain.links())]
    g = planar(chain).gravity
    return Chain(links, gravity=(0.0 if g is None else g) if gravity is None else gravity, contact=chain.contact,
                 limits=chain.limits)


def has_slide_below_hinge(chain: Chain) -> bool:
    joints = planar(chain).joints
    first_revolute = joints.index("revolute") if "revolute" in joints else len(joints)
    return "prismatic" in joints[first_revolute:]


def mujoco_model(chain: Chain, dt: float, integrator: str = "Euler"):
    """MuJoCo's compiled model of ``to_mjcf(chain)`` and its data."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(to_mjcf(chain, timestep=dt, integrator=integrator))
    return model, mujoco.MjData(model)


def mujoco_batch_rollout(model, data, q0, qd0, controls):
    """MuJoCo C ``mj_step`` rollouts of a batch, through ``mujoco.rollout`` (batched over leading dims of
    q0/qd0/controls), for the many rollouts of the trajectory and finite-difference checks; the library's
    :func:`lagrange.interop.mjcf.mujoco_rollout` steps one rollout from Python and reports constraints.

    q0, qd0: (B, n); controls: (B, T, m). Returns q, qd of shape (B, T, n) after each step.
    """
    from mujoco import rollout as mj_rollout_module

    q0, qd0, controls = np.atleast_2d(q0), np.atleast_2d(qd0), np.asarray(controls, dtype=float)
    if controls.ndim == 2:
        controls = controls[None]
    batch = max(q0.shape[0], controls.shape[0])
    n = model.nq
    state0 = np.zeros((batch, 1 + 2 * n))
    state0[:, 1 : 1 + n] = q0
    state0[:, 1 + n :] = qd0
    if model.nu == 0:
        controls = np.zeros(controls.shape[:2] + (0,))
    state, _ = mj_rollout_module.rollout(model, data, state0, np.broadcast_to(controls, (batch,) + controls.shape[1:]))
    return state[:, :, 1 : 1 + n], state[:, :, 1 + n :]


def mujoco_forward(model, q, qd, u):
    """MuJoCo's ``MjData`` after ``mj_forward`` at ``(qpos, qvel, ctrl) = (q, qd, u)``, and its dense mass matrix
    (``mj_fullM``)."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.ctrl[:] = q, qd, u
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return data, M


def mujoco_terms(model, q, qd, u):
    """MuJoCo's ``(M, qfrc_bias - qfrc_passive, qacc)`` at a state: what ``mass_matrix``, ``bias_forces`` and
    ``forward_dynamics`` of the model read by ``from_mjcf`` equal."""
    data, M = mujoco_forward(model, q, qd, u)
    return M, data.qfrc_bias - data.qfrc_passive, np.array(data.qacc)


def random_problem(chain: Chain, seed: int, steps: int = 500, *, scale=0.3, control_scale=1.0):
    rng = np.random.default_rng(seed)
    q0 = scale * rng.standard_normal(chain.nq)
    qd0 = scale * rng.standard_normal(chain.nv)
    us = control_scale * rng.standard_normal((steps, chain.m))
    return q0, qd0, us


def _all_chains():
    """The catalogue systems at their paper steps and ten seeded random chains, as pytest params (chain, dt)."""
    out = [pytest.param(make(), dt, id=name) for name, (make, dt) in SYSTEMS.items()]
    out += [pytest.param(seeded_chain(seed), 0.005, id=f"random{seed}") for seed in range(10)]
    return out


CHAINS = _all_chains()


# --------------------------------------------------------------- policies and trainers


def param_count(tree):
    """The number of array entries in a pytree (the parameters of an equinox module)."""
    return sum(x.size for x in jax.tree_util.tree_leaves(eqx.filter(tree, eqx.is_array)))


ROOT = pathlib.Path(__file__).resolve().parent.parent  # the repository: the cwd of subprocess tests


def tiny_ce_apg_config(**overrides):
    """A CE-APG config small enough for a test (4 candidates, 3 iterations of 2 APG steps of one episode), shared by
    the checkpoint, host-loop, CLI and CE-APG tests."""
    from optim import CEAPGConfig

    return CEAPGConfig(**{**dict(num_candidates=4, num_elites=2, iterations=3, apg_steps=2, episodes=1,
                                 fitness_window=1, lr_start=1e-2, lr_end=1e-3), **overrides})


def tiny_acrobot(horizon=20, **options):
    """The paper's acrobot (rods) cut to ``horizon`` control steps."""
    from lagrange.tasks import Acrobot

    return Acrobot.rods(horizon=horizon, **options)


def tiny_gru(task, width=4):
    """A GRU policy of ``width`` sized for ``task`` (the trainers draw its weights)."""
    from policies import GRUPolicy

    return GRUPolicy.for_task(task, width=width)


def tiny_mlp(task, width=4):
    """A one-hidden-layer MLP policy of ``width`` sized for ``task`` (it compiles faster than the GRU)."""
    from policies import MLPPolicy

    return MLPPolicy.for_task(task, width=width, depth=1)


def states_equal(a, b) -> bool:
    """Two pytrees with the same structure and bit-identical leaves."""
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    return (jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)
            and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(la, lb)))


def pendulum_swingup(horizon=100, noise=0.01, **options):
    """A small task: pendulum swing-up (1 kg, 1 m, torque 5 a N m; gravity's largest torque is 4.9 N m)
    with the acrobot's reward 10 - th^2 - 0.01 dth^2 per step, dt 0.05 s (``options``: other task fields, e.g.
    ``upright=1.0`` for a balance task)."""
    from lagrange.tasks import ChainSwingup

    return ChainSwingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=horizon, noise=noise, **options)


ALGORITHMS = ("CEAPGConfig", "CEMConfig", "PAPGConfig", "APGConfig", "SHACConfig")
"""The configs of the training algorithms, by class name."""

RUN_KEY, RUN_SEED, EVAL_KEY = jax.random.PRNGKey(7), 7, jax.random.PRNGKey(5)
"""The key and seed of the ``short_run`` fixture's runs, and the key of their evaluations' starts."""
EVALUATED = ("CEAPGConfig", "SHACConfig")
"""The ``short_run`` fixture's runs evaluated after every iteration: a CE search and SHAC's actor."""
SHARDED = ("CEAPGConfig", "PAPGConfig", "SHACConfig")
"""The runs compared between 1 and 2 devices (``tests/optim/test_devices.py``): the algorithms that shard."""


def small_problem(name, iterations=2):
    """``(config, task, policy, env steps per iteration)`` of a small run of the algorithm ``name`` (one of
    ``ALGORITHMS``) on the pendulum, the smallest task (the least to compile): 20-step episodes (6 for SHAC, so that
    episodes end inside its second 4-step window); CE-APG's 5 candidates are padded on 2 devices; SHAC's learning
    rates are constant and its target critic's ``alpha`` is not the default."""
    import optim
    from policies import Actor

    pendulum = pendulum_swingup(horizon=20, noise=0.5)
    if name == "CEAPGConfig":
        return tiny_ce_apg_config(num_candidates=5, iterations=iterations), pendulum, tiny_mlp(pendulum), 5 * 2 * 1 * 20
    if name == "CEMConfig":
        cfg = optim.CEMConfig(num_candidates=4, num_elites=2, iterations=iterations, episodes=2)
        return cfg, pendulum, tiny_gru(pendulum), 4 * 1 * 2 * 20
    if name == "PAPGConfig":
        cfg = optim.PAPGConfig(num_runs=2, iterations=iterations, apg_steps=2, episodes=1, fitness_window=1,
                               lr_start=1e-2, lr_end=1e-3)
        return cfg, pendulum, tiny_mlp(pendulum), 2 * 2 * 1 * 20
    if name == "APGConfig":
        cfg = optim.APGConfig(iterations=iterations, steps_per_iteration=2, episodes=2, learning_rate=1e-2)
        return cfg, pendulum, tiny_mlp(pendulum), 2 * 2 * 20
    if name != "SHACConfig":
        raise ValueError(f"unknown algorithm {name!r}")
    task = pendulum_swingup(horizon=6, noise=0.5)
    cfg = optim.SHACConfig(num_envs=4, short_horizon=4, iterations=iterations, critic_iterations=2,
                           critic_minibatches=2, critic_units=(8,), target_alpha=0.3, actor_lr=1e-3, critic_lr=1e-3,
                           lr_end=1e-3)
    return cfg, task, Actor.for_task(task, units=(8,)), 4 * 4


def reuse_trainers(monkeypatch, *known):
    """Within ``monkeypatch``'s scope, every config's ``make_trainer`` returns the trainer it built before for an equal
    config, the same task, policy and objective (objects), instead of building (and so compiling) it again: a trainer
    is a deterministic function of these. For a test that runs ``optim.train`` on the same problem more than once (an
    interrupted run and its resume), which would otherwise compile the same update again each time. ``known``:
    ``(trainer, policy)`` pairs built before, by ``trainer.config.make_trainer(trainer.task, policy)`` (the default
    objective), e.g. a ``short_run``'s, given back for that config, task and policy too."""
    import optim

    built = {(type(t.config), t.config, id(t.task), id(p), id(None)): (t, t.task, p, None) for t, p in known}

    def reusing(make):
        def make_trainer(self, task, policy, *, objective=None):
            key = (type(self), self, id(task), id(policy), id(objective))
            if key not in built:
                built[key] = (make(self, task, policy, objective=objective), task, policy, objective)  # ids held
            return built[key][0]

        return make_trainer

    classes, todo = [], [optim.AlgorithmConfig]
    while todo:
        cls = todo.pop()
        todo += cls.__subclasses__()
        if "make_trainer" in vars(cls) and not getattr(vars(cls)["make_trainer"], "__isabstractmethod__", False):
            classes.append(cls)
    for cls in classes:
        monkeypatch.setattr(cls, "make_trainer", reusing(vars(cls)["make_trainer"]))


def oracle_terms(chain, q, qd):
    """The Euler-Lagrange oracle's ``(M, bias, gravity)`` at one state, its gravity forces being its bias at rest.
    The two bias forces are one ``bias_forces`` vmapped over the velocities ``qd`` and ``0``: the oracle's dense
    Hessians are the costliest part of the tests that use it to compile, and this compiles them once, not twice."""
    from oracles import euler_lagrange as el

    bias = jax.vmap(lambda v: el.bias_forces(chain, q, v))(jnp.stack([qd, jnp.zeros_like(qd)]))
    return el.mass_matrix(chain, q), bias[0], bias[1]
