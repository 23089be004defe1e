"""Why SHAC's window gradient on DFlex's humanoid costs 7 forwards, and what recomputing each substep buys.

    python -m research.substep_remat            # the humanoid and the ant, about 2 minutes on 2 cores

SHAC's actor loss runs a 32-step window of 64 environments through ``task.step`` (48 semi-implicit Euler substeps
of the humanoid, 16 of the ant, the mass matrix held over a control step) and sums the rewards. Timed, float32, the
best of 3 calls after the first, all in one process: the forward window, and its gradient with respect to the
actions three ways: storing every substep's intermediates (DFlex's solver as it is), recomputing each control step in
the backward pass (``jax.checkpoint`` around ``task.step``), and recomputing each substep
(``SemiImplicitEuler(checkpoint_substeps=True)``, the humanoid's default solver). Prints seconds per call and the
largest difference of each gradient from the stored one's.
"""

from __future__ import annotations

import jax
import numpy as np

import lagrange as lg
from benchmarks._timing import median_time
from lagrange.tasks import Ant, Humanoid
from lagrange.tasks.locomotion import DFLEX_SOLVER

B, T = 64, 32


def measure(cls):
    task = cls.diffrl()
    s0 = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(0), B))
    actions = 0.3 * jax.random.normal(jax.random.PRNGKey(1), (T, B, task.action_size))
    stored = type(task).diffrl(solver=DFLEX_SOLVER)
    per_substep = type(task).diffrl(solver=lg.SemiImplicitEuler(implicit_damping=False, hold_mass_matrix=True,
                                                                checkpoint_substeps=True))

    def window(task, remat_steps):
        step = jax.checkpoint(lambda s, a: task.step(s, a)) if remat_steps else task.step

        def total(acts, s0):
            def body(s, a):
                s1 = jax.vmap(step)(s, a)
                return s1, jax.vmap(task.reward)(s, a, s1)

            return jax.lax.scan(body, s0, acts)[1].sum()

        return total

    opts = lg.compiler_options(task.chain)
    rows = {"forward": median_time(jax.jit(window(stored, False), compiler_options=opts), actions, s0, repeats=3,
                                   best=True)}
    grads = {}
    for name, (t, remat) in {"gradient, stored": (stored, False), "gradient, each control step recomputed":
                             (stored, True), "gradient, each substep recomputed": (per_substep, False)}.items():
        g = jax.jit(jax.grad(window(t, remat)), compiler_options=opts)
        rows[name] = median_time(g, actions, s0, repeats=3, best=True)
        grads[name] = np.asarray(g(actions, s0))
    ref = grads["gradient, stored"]
    for name, seconds in rows.items():
        diff = "" if name not in grads else f", max |diff| {np.max(np.abs(grads[name] - ref)):.1e} " \
                                            f"(of max |g| {np.max(np.abs(ref)):.1e})"
        print(f"{task.name:9s} {name:40s} {seconds:6.3f} s{diff}", flush=True)


if __name__ == "__main__":
    for cls in (Humanoid, Ant):
        measure(cls)
