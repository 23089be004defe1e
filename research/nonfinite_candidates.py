"""Which CE-APG candidates go non-finite, and is it the return or the gradient?

    python -m research.nonfinite_candidates --task custom_chain   # the example's default config
    python -m research.nonfinite_candidates --task cartpole       # Table I's (paper_tables, laptop)
    python -m research.nonfinite_candidates --task cartpole --bodies brax_v1

Re-runs the config (seed 0 unless ``--seed``) iteration by iteration on the devices this process has. In each
iteration with a non-finite candidate it re-draws that iteration's candidates exactly as ``optim.ce_apg`` does and
re-runs every candidate's APG steps with a diagnostic copy of ``optim.apg_steps`` that also records, per APG step,
the largest |qd| of each coordinate over the batch's episodes, whether the batch return and the gradient are finite,
and the largest |gradient| entry. For each non-finite candidate it prints the first non-finite step, which of the two
failed, and the largest speeds and gradient before it; for the first three finite ones the same maxima. With
``--float64`` each non-finite candidate's APG steps are run again in float64 from the same parameters, normaliser and
keys (the reset noise is drawn in float64 from the same keys, so the starts differ in the last float32 bits), to see
whether the float32 failure is an overflow of a gradient that float64 still represents. Stops after ``--max-found``
non-finite candidates or ``--iterations``. Each candidate is re-run alone where the trainer runs them vmapped, so
float32 round-off differs and a replayed candidate need not fail where the trainer's did (the trainer's count per
iteration is printed beside).
"""

import argparse
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np
import optax

from benchmarks import paper_tables
from benchmarks._cli import add_bodies_flag
from optim import episode, flatten_policy
from policies import GRUPolicy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))


def diagnostic_apg(task, cfg, unravel):
    """``run(theta, normalizer, key, lr) -> (batch return, max |qd| per coordinate, return finite, gradient finite,
    max |gradient|)`` per APG step: the same updates as ``optim.apg_steps``."""
    adam = optax.scale_by_adam()

    def loss(p, norm, keys):
        eps = jax.vmap(lambda k: episode(task, unravel(p), norm, k, truncation=cfg.truncation))(keys)
        return -jnp.mean(eps.ret), (eps.obs, jnp.max(jnp.abs(eps.qd), axis=(0, 1)))

    grad_fn = jax.value_and_grad(loss, has_aux=True)

    def run(theta, norm, key, lr):
        def body(carry, i):
            p, opt, norm, ok = carry
            keys = jax.random.split(jax.random.fold_in(key, i), cfg.episodes)
            (value, (obs, vmax)), g = grad_fn(p, norm, keys)
            v_finite, g_finite = jnp.isfinite(value), jnp.all(jnp.isfinite(g))
            good = ok & v_finite & g_finite
            upd, opt2 = adam.update(jnp.where(good, g, 0.0), opt)
            keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
            carry = (keep(p - lr * upd, p), keep(opt2, opt), keep(norm.update(obs), norm), good)
            return carry, (-value, vmax, v_finite, g_finite, jnp.max(jnp.abs(g)))

        init = (theta, adam.init(theta), norm, jnp.asarray(True))
        return jax.lax.scan(body, init, jnp.arange(cfg.apg_steps))[1]

    return jax.jit(run)


def setup(args):
    """``(config, build)`` of the run to replay: ``build() -> (task, policy)`` (called again under float64)."""
    if args.task == "custom_chain":
        import custom_chain

        def build():
            task = custom_chain.make_task()
            return task, GRUPolicy.for_task(task, width=16)  # the example's policy

        return custom_chain.CONFIG, build
    protocol = paper_tables.with_overrides(paper_tables.config("ce_apg", args.task, "laptop"), {"bodies": args.bodies})

    def build():
        task = protocol.make_task()
        return task, protocol.make_policy(task)

    return protocol.config, build


def float64_diagnostic(cfg, build):
    """``run(theta, normalizer, key, lr)``: the diagnostic APG steps of one candidate in float64 (task and policy
    template rebuilt under x64 once, so every call reuses one compilation; inputs cast to float64)."""
    with jax.enable_x64(True):
        task64, policy64 = build()
        _, unravel = flatten_policy(policy64)
        run64 = diagnostic_apg(task64, cfg, unravel)

    def run(theta, norm, key, lr):
        with jax.enable_x64(True):
            norm64 = jax.tree_util.tree_map(lambda x: jnp.asarray(x, jnp.float64), norm)
            out = run64(jnp.asarray(theta, jnp.float64), norm64, key, jnp.asarray(lr, jnp.float64))
            return tuple(np.asarray(x) for x in out)

    return run


def describe(ret, vmax, v_finite, g_finite, gmax):
    ok = np.isfinite(ret) & v_finite & g_finite
    if ok.all():
        return (f"all {ok.size} steps finite; max |qd| {np.array2string(vmax.max(0), precision=1)}, "
                f"max |gradient| {gmax.max():.1e}, last return {ret[-1]:.1f}")
    bad = int(np.argmin(ok))
    what = " and ".join(w for w, f in (("return", v_finite[bad]), ("gradient", g_finite[bad])) if not f)
    at = f"at it max |qd| {np.array2string(vmax[bad], precision=1)}"
    if bad == 0:
        return f"non-finite at the first APG step ({what}); {at}"
    return (f"first non-finite APG step {bad} ({what}); before it max |qd| "
            f"{np.array2string(vmax[:bad].max(0), precision=1)}, max |gradient| {gmax[:bad].max():.1e}; {at}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="custom_chain", choices=("custom_chain",) + paper_tables.TASKS)
    add_bodies_flag(p)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--iterations", type=int, default=12)
    p.add_argument("--max-found", type=int, default=4)
    p.add_argument("--float64", action="store_true", help="re-run each non-finite candidate in float64")
    args = p.parse_args(argv)
    if args.task == "custom_chain" and args.bodies != "rods":
        p.error("--bodies is for the paper tasks; custom_chain has the example's own bodies")
    cfg, build = setup(args)
    if cfg.warmup_horizons or cfg.upright_starts or cfg.train_noise is not None or cfg.authors_normalizer:
        raise SystemExit("nonfinite_candidates replays configs without curriculum stages, upright starts, "
                         "train_noise or the authors' normaliser only")
    task, policy = build()
    trainer = cfg.make_trainer(task, policy)
    _, unravel = flatten_policy(policy)
    run = diagnostic_apg(trainer.task, cfg, unravel)
    run64 = float64_diagnostic(cfg, build) if args.float64 else None
    state = trainer.init(jax.random.PRNGKey(args.seed))
    found = 0
    for it in range(args.iterations):
        k_eps, k_run = jax.random.split(jax.random.fold_in(state.key, state.iteration))  # as the CE-APG update
        lr = cfg.learning_rate(state.iteration)
        thetas = state.mean + state.std * jax.random.normal(k_eps, (cfg.num_candidates, state.mean.size))
        keys = jax.random.split(k_run, cfg.num_candidates)
        new, metrics = trainer.update(state)
        n_bad = int(metrics["nonfinite"])
        print(f"iteration {it + 1}: {n_bad} non-finite, best {float(metrics['best_return']):.1f}", flush=True)
        if n_bad:
            finite_shown = 0
            for c in range(cfg.num_candidates):
                out = tuple(np.asarray(x) for x in run(thetas[c], state.normalizer, keys[c], lr))
                ret, _, v_finite, g_finite, _ = out
                if (np.isfinite(ret) & v_finite & g_finite).all():
                    if finite_shown < 3:
                        print(f"   finite candidate {c}: {describe(*out)}")
                        finite_shown += 1
                    continue
                print(f"   candidate {c}: {describe(*out)}", flush=True)
                if run64 is not None:
                    print(f"      float64: {describe(*run64(thetas[c], state.normalizer, keys[c], lr))}", flush=True)
                found += 1
        state = new
        if found >= args.max_found:
            break


if __name__ == "__main__":
    main()
