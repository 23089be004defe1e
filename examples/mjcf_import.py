"""Import Gymnasium's inverted double pendulum from MJCF, identify its masses and damping, train a policy on it.

1. ``from_mjcf`` reads the model (``q``, ``qd``, ``u`` = MuJoCo's ``qpos``, ``qvel``, ``ctrl``); from 256 windows of 5
   ``mj_step``s and bodies twice as heavy, joints damped 0.3, ``optim.identify`` recovers masses and damping.
2. CE-APG trains a GRU through the identified tree to balance both poles for 5 s; the policy then drives MuJoCo.

    python examples/mjcf_import.py [--model PATH] [--seed S]     # needs pip install -e ".[test]"
"""

import argparse
import dataclasses
import pathlib

import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from lagrange.interop.mjcf import from_mjcf, mujoco_rollout, solver_of
from lagrange.tasks import DoubleCartpole, TaskState
from optim import CEAPGConfig, evaluate, train
from optim.identify import identify
from policies import GRUPolicy

MODEL = pathlib.Path(gymnasium.__file__).parent / "envs" / "mujoco" / "assets" / "inverted_double_pendulum.xml"
TURN = np.array([0.0, np.pi, 0.0])  # the task counts the first pole from hanging, the model from upright


def scaled(tree, theta):
    """``tree`` with each body's mass and inertia times ``exp(theta[:n])`` (a density guess) and each joint's damping
    ``exp(theta[n:])``: the cart and the two poles, one joint each."""
    where = lambda t: [x for b in t.bodies for x in (b.mass, b.inertia)] + [j.damping for j in t.joints]  # noqa: E731
    s = jnp.exp(theta)
    return eqx.tree_at(where, tree, [x * s[i // 2] for i, x in enumerate(where(tree)[:-3])] + list(s[3:]))


def main(path, seed):
    model = mujoco.MjModel.from_xml_path(str(path))  # compiled once, read by every call below
    tree, (solver, dt) = from_mjcf(model, limits="ignore"), solver_of(model)  # the data stay inside the rail's limits
    rng, windows = np.random.default_rng(seed), []
    while len(windows) < 256:
        q0 = np.concatenate([rng.uniform(-0.7, 0.7, 1), rng.uniform(-np.pi, np.pi, tree.nv - 1)])
        u = np.full((5, tree.m), rng.uniform(-1, 1))
        x, met = mujoco_rollout(model, q0, rng.uniform(-3, 3, tree.nv), u)
        windows += [] if met else [(x, u)]
    states, controls = (np.array(a, np.float32) for a in zip(*windows))
    theta0 = np.log(np.r_[np.full(tree.nv, 2.0), np.full(tree.nv, 0.3)]).astype(np.float32)
    fit = identify(lambda th: scaled(tree, th), theta0, states, controls, dt, solver, iterations=80)
    damping = lambda t: np.array([float(j.damping) for j in t.joints])  # noqa: E731
    for name, got, true in (("masses", fit.chain.mass, tree.mass), ("damping", damping(fit.chain), damping(tree))):
        print(f"{name}: {np.round(got, 5)}, model's {np.round(true, 5)}, off by {np.max(abs(got / true - 1)):.1e}")
    pole = lambda t: t.bodies[1].joints[0]  # noqa: E731  upright as written: ref = pi counts it from hanging, as the task
    task = DoubleCartpole(eqx.tree_at(pole, fit.chain, dataclasses.replace(pole(fit.chain), ref=np.pi)), upright=1.0,
                          noise=0.05)  # 500 steps, 5 s
    config = CEAPGConfig(num_candidates=8, num_elites=3, iterations=60, apg_steps=25, episodes=2, lr_start=1e-2,
                         lr_end=1e-4, init_std=0.15, warmup_horizons=(100, 150, 200, 300, 400), warmup_iterations=10)
    result = train(config, task, GRUPolicy.for_task(task, key=jax.random.PRNGKey(seed)), jax.random.PRNGKey(seed))
    policy, normalizer = result.trainer.policy(result.state)
    returns, held = evaluate(task, policy, normalizer, jax.random.PRNGKey(10_000), 16)
    print(f"balance for 5 s: return {float(returns.mean()):.0f} of 5000, {int(held.sum())}/16 held (lagrange)")
    act = jax.jit(lambda obs, h, t: policy(normalizer(obs), h, t == 0))
    held_mj = 0
    for _episode in range(8):  # the same policy driving MuJoCo on the original model
        x, h, met = rng.uniform(-0.05, 0.05, 2 * tree.nv), policy.initial_state(), False
        for t in range(task.horizon):
            obs = task.observe(TaskState(jnp.asarray(x[: tree.nv] + TURN, jnp.float32), jnp.asarray(x[tree.nv:])))
            a, h = act(obs, h, t)
            xs, hit = mujoco_rollout(model, x[: tree.nv], x[tree.nv:], np.asarray(a, float))
            x, met = xs[-1], met or hit
        held_mj += int(not met and max(abs(x[1]), abs(x[1] + x[2])) < 0.2)
    print(f"the same policy driving MuJoCo (mj_step, the model's own masses): {held_mj}/8 held for 5 s")

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=pathlib.Path, default=MODEL)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    main(args.model, args.seed)
