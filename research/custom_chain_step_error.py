"""Is one RK4 step per 0.02 s interval accurate enough for ``examples/custom_chain.py``? Measured in float64.

    python examples/custom_chain.py                          # the trained policy (runs/custom_chain/checkpoint.eqx)
    python -m research.custom_chain_step_error # about 2 minutes

One control interval from each state with RK4 and 1, 2, 4 (8) substeps against ``Dopri8`` at rtol = atol = 1e-12
(1e-13 for the random states); the error of an interval is the larger of max |dq| and dt * max |dqd|.

1. along the 16 evaluation episodes of the trained policy (the example's evaluation starts, seed 0; its float32
   episode re-stepped in float64 from every visited state with the action it took);
2. from random states (30 per row: angles uniform, each velocity uniform in +-bound, random torque);
3. how fast a bang-bang torque on both motors (periods 0.5, 1 and 2 s, out of phase) drives the chain in 5 s
   (Dopri8 episodes).
"""

import argparse
import os
import sys

import jax
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))

import custom_chain  # noqa: E402
import diffrax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import lagrange as lg  # noqa: E402
from optim import episode  # noqa: E402
from policies import GRUPolicy  # noqa: E402
from research._cli import load_run  # noqa: E402


def trained_states(checkpoint):
    """The trained policy's visited (q, qd) and actions (clipped), flattened over its 16 evaluation episodes."""
    task = custom_chain.make_task()
    trainer, state = load_run(checkpoint, task, GRUPolicy.for_task(task, width=16))  # the example's policy
    policy, norm = trainer.policy(state)
    keys = jax.random.split(jax.random.PRNGKey(10_000), 16)
    eps = jax.jit(jax.vmap(lambda k: episode(trainer.task, policy, norm, k)))(keys)
    flat = lambda x: np.asarray(x).reshape(-1, x.shape[-1])
    return flat(eps.q[:, :-1]), flat(eps.qd[:, :-1]), np.clip(flat(eps.actions), -1, 1)


def interval_errors(chain, dt, q, qd, u, substeps, tol):
    """Per state: the one-interval error of RK4 with each of ``substeps`` against Dopri8 at ``tol``."""
    q, qd, u = (jnp.asarray(x, jnp.float64) for x in (q, qd, u))
    ref = jax.jit(jax.vmap(lambda a, b, c: lg.step(chain, a, b, c, dt, diffrax.Dopri8(), rtol=tol, atol=tol,
                                                   max_steps=100_000)))
    rq, rv = ref(q, qd, u)
    out = {}
    for s in substeps:
        sq, sv = jax.jit(jax.vmap(lambda a, b, c, s=s: lg.step(chain, a, b, c, dt, lg.RK4(), substeps=s)))(q, qd, u)
        err = np.maximum(np.abs(np.asarray(sq - rq)).max(-1), dt * np.abs(np.asarray(sv - rv)).max(-1))
        out[s] = np.where(np.isfinite(err), err, np.inf)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="runs/custom_chain/checkpoint.eqx")
    args = p.parse_args(argv)
    q, qd, u = trained_states(args.checkpoint) if os.path.exists(args.checkpoint) else (None, None, None)
    jax.config.update("jax_enable_x64", True)
    task = custom_chain.make_task()  # now in float64
    chain, dt = task.chain, task.dt
    if q is None:
        print(f"{args.checkpoint} not found: run python examples/custom_chain.py first for part 1")
    else:
        print(f"1. the trained policy's episodes: max |qd| {np.abs(qd).max():.1f} rad/s")
        for s, e in interval_errors(chain, dt, q, qd, u, (1, 2, 4), 1e-12).items():
            print(f"   RK4 x{s}: median {np.median(e):.1e}, 99th percentile {np.percentile(e, 99):.1e}, "
                  f"max {e.max():.1e}")
    print("2. random states, median / max one-interval error of 30")
    rng = np.random.default_rng(0)
    for bound in (2, 5, 10, 20, 40, 80):
        q = rng.uniform(-np.pi, np.pi, (30, 3))
        qd = rng.uniform(-bound, bound, (30, 3))
        u = rng.uniform(-1, 1, (30, 2))
        errs = interval_errors(chain, dt, q, qd, u, (1, 2, 4, 8), 1e-13)
        print(f"   |qd| <= {bound:2d}: " + "  ".join(f"x{s} {np.median(e):.1e}/{e.max():.1e}" for s, e in errs.items()))
    print("3. bang-bang torque from hanging, Dopri8 over 5 s")
    t = np.arange(task.horizon) * dt
    for period in (0.5, 1.0, 2.0):
        a = np.stack([np.sign(np.sin(2 * np.pi * t / period)), np.sign(np.sin(2 * np.pi * t / period + 1.0))], 1)
        ref = lg.simulate(chain, jnp.asarray([0.01, -0.01, 0.005]), jnp.zeros(3), jnp.asarray(a), dt,
                          solver=diffrax.Dopri8(), rtol=1e-12, atol=1e-12, max_steps=100_000)
        print(f"   period {period} s: max |qd| {float(jnp.max(jnp.abs(ref.qd))):.1f} rad/s")


if __name__ == "__main__":
    main()
