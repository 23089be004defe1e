"""Does a hold exist for ``examples/custom_chain.py``'s chain? The saturated LQR from 16 upright starts.

    python -m research.custom_chain_lqr      # seconds

The gain is ``research.upright_basin``'s (Q = diag(1, 1, 1, 0.01, 0.01, 0.01), R = r) on the one-interval
linearisation at upright; actions are ``clip(-K dx, -1, 1)``; the starts are the task's upright starts (+-0.01).
Prints the return (of 2500) and how many of the 16 episodes are ``balanced``.
"""

import dataclasses
import os
import sys

import jax
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))

import custom_chain  # noqa: E402

from lagrange.control import linearise, saturated_lqr  # noqa: E402
from lagrange.tasks import balanced  # noqa: E402
from research.upright_basin import upright_lqr  # noqa: E402


def main():
    task = custom_chain.make_task()
    A, B = linearise(task)
    print(f"open-loop spectral radius {np.abs(np.linalg.eigvals(A)).max():.4f}")
    upright = dataclasses.replace(task, upright=1.0)
    for r in (1.0, 100.0):
        K = upright_lqr(task, r)
        controller = saturated_lqr(task, K)

        def episode(key):
            def body(s, _):
                a = controller(s.q, s.qd)
                s2 = task.step(s, a)
                return s2, (task.reward(s, a, s2), s2.q)

            _, (rewards, q) = jax.lax.scan(body, upright.reset(key), None, length=task.horizon)
            return rewards.sum(), q

        returns, q = jax.jit(jax.vmap(episode))(jax.random.split(jax.random.PRNGKey(0), 16))
        radius = np.abs(np.linalg.eigvals(A - B @ K)).max()
        print(f"r = {r}: return {float(returns.mean()):.1f} of {10 * task.horizon}, balanced "
              f"{int(balanced(task, q).sum())} of 16, closed-loop spectral radius {radius:.4f}")


if __name__ == "__main__":
    main()
