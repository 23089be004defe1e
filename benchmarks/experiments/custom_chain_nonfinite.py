"""Which candidates of ``examples/custom_chain.py``'s CE-APG go non-finite, and how fast is the chain moving then?

    python -m benchmarks.experiments.custom_chain_nonfinite   # about 2 minutes on one CPU device

Re-runs the example's default config (seed 0, one CPU device) iteration by iteration. In each iteration with a
non-finite candidate it re-draws that iteration's candidates exactly as ``optim.ce_apg`` does and re-runs every
candidate's APG steps with a diagnostic copy of ``optim.apg.apg_steps`` that also records, per APG step, the largest
|qd| of the batch's episodes and whether the gradient is finite; it prints those of the non-finite candidates (up to
the first non-finite step) and the largest |qd| of the first three finite ones. Stops after ``--max-found``.
"""

import argparse
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np
import optax

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples"))

import custom_chain  # noqa: E402

from optim import ce_apg  # noqa: E402
from optim.apg import build_policy, episode, flatten_policy  # noqa: E402


def diagnostic_apg(task, cfg, unravel):
    """``run(theta, normalizer, key, lr) -> (batch return, max |qd|, gradient finite, max |gradient|)`` per APG step,
    the same updates as ``optim.apg.apg_steps``."""
    adam = optax.scale_by_adam()

    def loss(p, norm, keys):
        eps = jax.vmap(lambda k: episode(task, unravel(p), norm, k))(keys)
        return -jnp.mean(eps.ret), (eps.obs, jnp.max(jnp.abs(eps.qd)))

    grad_fn = jax.value_and_grad(loss, has_aux=True)

    def run(theta, norm, key, lr):
        def body(carry, i):
            p, opt, norm, ok = carry
            keys = jax.random.split(jax.random.fold_in(key, i), cfg.episodes)
            (value, (obs, vmax)), g = grad_fn(p, norm, keys)
            g_finite = jnp.all(jnp.isfinite(g))
            good = ok & jnp.isfinite(value) & g_finite
            g = jnp.where(good, g, 0.0)
            upd, opt2 = adam.update(g, opt)
            keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
            carry = (keep(p - lr * upd, p), keep(opt2, opt), keep(norm.update(obs), norm), good)
            return carry, (-value, vmax, g_finite, jnp.max(jnp.abs(g)))

        init = (theta, adam.init(theta), norm, jnp.asarray(True))
        return jax.lax.scan(body, init, jnp.arange(cfg.apg_steps))[1]

    return jax.jit(run)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--iterations", type=int, default=12)
    p.add_argument("--max-found", type=int, default=4)
    args = p.parse_args(argv)
    cfg = custom_chain.CONFIG
    trainer = ce_apg.make_trainer(cfg, custom_chain.make_task())
    _, unravel = flatten_policy(build_policy(cfg, trainer.task, jax.random.PRNGKey(0)))
    run = diagnostic_apg(trainer.task, cfg, unravel)
    state = trainer.init(jax.random.PRNGKey(0))
    found = 0
    for it in range(args.iterations):
        k_eps, k_run = jax.random.split(jax.random.fold_in(state.key, state.iteration))  # as optim.ce_apg.update
        lr = cfg.learning_rate(state.iteration)
        thetas = state.mean + state.std * jax.random.normal(k_eps, (cfg.num_candidates, state.mean.size))
        keys = jax.random.split(k_run, cfg.num_candidates)
        new, metrics = trainer.update(state)
        print(f"iteration {it + 1}: {int(metrics['nonfinite'])} non-finite", flush=True)
        if int(metrics["nonfinite"]):
            finite_shown = 0
            for c in range(cfg.num_candidates):
                ret, vmax, g_finite, gmax = (np.asarray(x) for x in run(thetas[c], state.normalizer, keys[c], lr))
                ok = np.isfinite(ret) & g_finite
                if ok.all():
                    if finite_shown < 3:
                        print(f"   finite candidate {c}: max |qd| {vmax.max():.1f} rad/s, max |gradient| {gmax.max():.1e}")
                        finite_shown += 1
                    continue
                bad = int(np.argmin(ok))
                print(f"   candidate {c}: first non-finite APG step {bad}; max |qd| before it "
                      f"{vmax[:bad].max():.1f} rad/s; max |gradient| before it {gmax[:bad].max():.1e}")
                found += 1
        state = new
        if found >= args.max_found:
            break


if __name__ == "__main__":
    main()
