"""CE-APG, SHAC, Brax PPO, Brax SAC and Brax APG on the paper's three tasks, on the same dynamics.

    python -m benchmarks.algorithms --quick            # smoke-scale budgets, 1 seed (what this repo's table shows)
    python -m benchmarks.algorithms --seeds 8          # the paper's budgets, 8 seeds (days on two CPU cores)

Every algorithm trains on the same task objects (:func:`lagrange.tasks.make_task`; the Brax trainers see
them through :class:`lagrange.envs.BraxEnv`, unchanged). The final policy of each run is evaluated
*deterministically* by this script on the same 16 random starts (``PRNGKey(10_000 + seed)``), with the
task's own 500-step return and :func:`lagrange.tasks.balanced`. Learning curves are deterministic
evaluation returns against simulated environment steps and against wall-clock seconds since the start of
the run (compilation and evaluation included). Brax's curves use Brax's own evaluator
(``deterministic_eval=True``) on its own random starts.

Budgets (``FULL`` below): CE-APG the authors' protocol (``CEAPGConfig.paper``, 200 iterations x 4.8e6
steps); SHAC the authors' cartpole config (64 envs x 32-step windows x 500 epochs, 1e6 steps); PPO, SAC
and Brax APG the hyperparameters of the CE-APG paper's appendix IX-C (PPO 8e7 steps, 512 envs, batch 256,
32 minibatches, unroll 50, 8 update epochs, discount 0.99, lr 3e-4, entropy 1e-3; SAC 2e6 steps, 64 envs,
batch 128, discount 0.95, lr 1e-3; Brax APG 1e7 steps, 24 envs, lr 5e-4, whole 500-step episodes per
update). ``QUICK`` shrinks every budget (and PPO's batch geometry) to a smoke test; the numbers it gives
are not a comparison of the algorithms.

Writes ``benchmarks/results/algorithms[_quick].json`` and ``.md`` (table) and one
``algorithms[_quick]_<task>.png`` per task (curves against env steps and against wall-clock).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import matplotlib

matplotlib.use("Agg")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lagrange.tasks import balanced, make_task  # noqa: E402
from optim import ce_apg, shac  # noqa: E402
from optim.apg import episode  # noqa: E402

TASKS = ("acrobot", "cartpole", "double_cartpole")
ALGORITHMS = ("ce_apg", "shac", "ppo", "sac", "brax_apg")
EVAL_EPISODES = 16
HORIZON = 500

# Paper Table I (mean, std over 8 seeds); the CE-APG paper calls the cartpole "Pendulum" and the
# double cartpole "Double Pendulum".
PAPER = {
    "ce_apg": {"cartpole": (-355, 10), "acrobot": (3053, 458), "double_cartpole": (4295, 75)},
    "ppo": {"cartpole": (-464, 223), "acrobot": (405, 927), "double_cartpole": (4249, 549)},
    "sac": {"cartpole": (-2274, 1000), "acrobot": (359, 159), "double_cartpole": (-3.9e5, 4.9e6)},
    "brax_apg": {"cartpole": (-3485, 819), "acrobot": (1949, 814), "double_cartpole": (-1982, 4056)},
}

FULL = {
    "ce_apg": {},  # CEAPGConfig.paper(task)
    "shac": {},  # SHACConfig defaults (the SHAC authors' config), the task's 500-step episodes
    "ppo": dict(num_timesteps=80_000_000, num_envs=512, batch_size=256, num_minibatches=32, unroll_length=50,
                num_updates_per_batch=8, discounting=0.99, learning_rate=3e-4, entropy_cost=1e-3,
                normalize_observations=True, num_evals=20),
    "sac": dict(num_timesteps=2_000_000, num_envs=64, batch_size=128, discounting=0.95, learning_rate=1e-3,
                normalize_observations=True, num_evals=20),
    "brax_apg": dict(env_steps=10_000_000, num_envs=24, learning_rate=5e-4, horizon_length=HORIZON,
                     normalize_observations=True, num_evals=20),
}

QUICK = {
    "ce_apg": dict(num_candidates=4, num_elites=2, iterations=3, apg_steps=5, episodes=2),
    "shac": dict(num_envs=32, epochs=40),
    "ppo": dict(num_timesteps=60_000, num_envs=64, batch_size=64, num_minibatches=4, unroll_length=50,
                num_updates_per_batch=8, discounting=0.99, learning_rate=3e-4, entropy_cost=1e-3,
                normalize_observations=True, num_evals=3),
    "sac": dict(num_timesteps=30_000, num_envs=64, batch_size=128, discounting=0.95, learning_rate=1e-3,
                normalize_observations=True, num_evals=3),
    "brax_apg": dict(env_steps=72_000, num_envs=24, learning_rate=5e-4, horizon_length=HORIZON,
                     normalize_observations=True, num_evals=3),
}


class _BraxPolicy:
    """A Brax inference function ``f(obs, key) -> (action, extras)`` with the rollout interface of
    :func:`optim.apg.episode` (stateless; normalisation is inside the Brax parameters)."""

    def __init__(self, fn):
        self.fn = fn

    def initial_state(self):
        return jnp.zeros(0, jnp.float32)

    def __call__(self, obs, hidden, reset=False):
        action, _ = self.fn(obs.astype(jnp.float32), jax.random.PRNGKey(0))
        return action, hidden


def _evaluate(task, policy, normalizer, seed):
    @jax.jit
    def run(key):
        eps = jax.vmap(lambda k: episode(task, policy, normalizer, k))(jax.random.split(key, EVAL_EPISODES))
        return eps.ret, balanced(task, eps.q)

    rets, bal = jax.device_get(run(jax.random.PRNGKey(10_000 + seed)))
    return np.asarray(rets, float), np.asarray(bal, bool)


# ---------------------------------------------------------------------------------------------
# one run per algorithm: returns (final returns, balanced flags, curve, env_steps, wall_clock)


def run_ce_apg(name, seed, budget):
    cfg = ce_apg.CEAPGConfig.paper(name, **budget)
    trainer = ce_apg.make_trainer(cfg)
    t0 = time.perf_counter()
    state = trainer.init(jax.random.PRNGKey(seed))
    curve, steps = [], 0.0
    for _ in range(cfg.iterations):
        state, _m = trainer.update(state)
        steps += cfg.env_steps_per_iteration()
        pol, norm = trainer.policy(state, "best")
        rets, _ = _evaluate(trainer.task, pol, norm, seed)
        curve.append((steps, time.perf_counter() - t0, float(rets.mean())))
    rets, bal = _evaluate(trainer.task, *trainer.policy(state, "best"), seed)
    return rets, bal, curve, steps, time.perf_counter() - t0


def run_shac(name, seed, budget):
    cfg = shac.SHACConfig(task=name, **budget)
    trainer = shac.make_trainer(cfg)
    t0 = time.perf_counter()
    every = max(1, cfg.epochs // 10)
    state = trainer.init(jax.random.PRNGKey(seed))
    curve, steps = [], 0.0
    for epoch in range(1, cfg.epochs + 1):
        state, _m = trainer.update(state)
        steps += cfg.env_steps_per_epoch()
        if epoch % every == 0 or epoch == cfg.epochs:
            rets, _ = _evaluate(trainer.task, *trainer.policy(state), seed)
            curve.append((steps, time.perf_counter() - t0, float(rets.mean())))
    rets, bal = _evaluate(trainer.task, *trainer.policy(state), seed)
    return rets, bal, curve, steps, time.perf_counter() - t0


def _run_brax(kind, name, seed, budget):
    from lagrange.envs import BraxEnv

    task = make_task(name)
    env = BraxEnv(task)
    budget = dict(budget)
    curve = []
    t0 = time.perf_counter()
    common = dict(environment=env, episode_length=HORIZON, seed=seed, deterministic_eval=True, num_eval_envs=16)
    if kind == "ppo":
        from brax.training.agents.ppo import train as ppo

        steps_total = budget["num_timesteps"]
        fn = ppo.train
        progress = lambda step, m: curve.append((float(step), time.perf_counter() - t0,
                                                 float(m["eval/episode_reward"])))
    elif kind == "sac":
        from brax.training.agents.sac import train as sac

        steps_total = budget["num_timesteps"]
        fn = sac.train
        progress = lambda step, m: curve.append((float(step), time.perf_counter() - t0,
                                                 float(m["eval/episode_reward"])))
    else:
        from brax.training.agents.apg import train as apg

        per_update = budget["num_envs"] * budget["horizon_length"]
        updates = max(1, int(budget.pop("env_steps")) // per_update)
        budget["policy_updates"] = updates
        # Brax APG runs round(updates / (num_evals - 1)) updates between evaluations and reports the
        # evaluation index as its step; convert to simulated steps.
        per_eval = int(round(updates / max(budget["num_evals"] - 1, 1))) * per_update
        steps_total = per_eval * max(budget["num_evals"] - 1, 1)
        fn = apg.train
        progress = lambda step, m: curve.append((float(step) * per_eval, time.perf_counter() - t0,
                                                 float(m["eval/episode_reward"])))
    make_policy, params, _ = fn(**common, **budget, progress_fn=progress)
    pol = _BraxPolicy(make_policy(params, deterministic=True))
    rets, bal = _evaluate(task, pol, None, seed)
    steps = curve[-1][0] if curve and kind != "brax_apg" else float(steps_total)
    return rets, bal, curve, steps, time.perf_counter() - t0


RUNNERS = {
    "ce_apg": run_ce_apg,
    "shac": run_shac,
    "ppo": lambda n, s, b: _run_brax("ppo", n, s, b),
    "sac": lambda n, s, b: _run_brax("sac", n, s, b),
    "brax_apg": lambda n, s, b: _run_brax("brax_apg", n, s, b),
}

LABELS = {"ce_apg": "CE-APG", "shac": "SHAC", "ppo": "Brax PPO", "sac": "Brax SAC", "brax_apg": "Brax APG"}


# ---------------------------------------------------------------------------------------------


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smoke-scale budgets (QUICK)")
    p.add_argument("--seeds", type=int, default=None, help="number of seeds (default: 1 with --quick, else 8)")
    p.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    p.add_argument("--algorithms", nargs="+", default=list(ALGORITHMS), choices=ALGORITHMS)
    p.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    p.add_argument("--plot-only", action="store_true", help="redo the table and plots from the saved JSON")
    args = p.parse_args(argv)
    seeds = args.seeds if args.seeds is not None else (1 if args.quick else 8)
    if seeds < 1:
        raise SystemExit(f"--seeds must be >= 1, got {seeds}")
    budgets = QUICK if args.quick else FULL
    tag = "algorithms_quick" if args.quick else "algorithms"
    os.makedirs(args.out, exist_ok=True)
    json_path = os.path.join(args.out, f"{tag}.json")
    if args.plot_only:
        with open(json_path) as f:
            results = json.load(f)
        write_table(results, os.path.join(args.out, f"{tag}.md"))
        for name in results["runs"]:
            plot_task(name, results["runs"][name], os.path.join(args.out, f"{tag}_{name}.png"), args.quick)
        return results
    results = {"meta": {"quick": args.quick, "seeds": seeds, "budgets": {a: budgets[a] for a in args.algorithms},
                        "eval_episodes": EVAL_EPISODES, "jax": jax.__version__, "devices": str(jax.devices()),
                        "machine": platform.platform(), "cpus": os.cpu_count()},
               "runs": {}}
    if os.path.exists(json_path):  # keep runs of tasks/algorithms not redone now
        with open(json_path) as f:
            old = json.load(f)
        if old.get("meta", {}).get("seeds") == seeds:
            results["runs"] = old.get("runs", {})
            results["meta"]["budgets"] = {**old["meta"].get("budgets", {}), **results["meta"]["budgets"]}
    for name in args.tasks:
        for algo in args.algorithms:
            runs = []
            for seed in range(seeds):
                print(f"{name:16s} {LABELS[algo]:9s} seed {seed} ...", flush=True)
                rets, bal, curve, steps, wall = RUNNERS[algo](name, seed, budgets[algo])
                runs.append({"seed": seed, "return": float(rets.mean()), "returns": rets.tolist(),
                             "balanced_fraction": float(bal.mean()), "env_steps": float(steps),
                             "wall_clock": float(wall), "curve": curve})
                print(f"{'':16s} {'':9s} return {rets.mean():.1f}, balanced {bal.mean():.0%}, "
                      f"{steps:.2e} steps, {wall:.0f} s", flush=True)
            results["runs"].setdefault(name, {})[algo] = runs
            with open(json_path, "w") as f:
                json.dump(results, f, indent=1)
    write_table(results, os.path.join(args.out, f"{tag}.md"))
    for name in results["runs"]:
        plot_task(name, results["runs"][name], os.path.join(args.out, f"{tag}_{name}.png"), args.quick)
    return results


def write_table(results, path):
    seeds = results["meta"]["seeds"]
    lines = [f"Final deterministic return over {EVAL_EPISODES} random starts, mean +- std over {seeds} seed(s) "
             f"({'QUICK smoke-scale budgets' if results['meta']['quick'] else 'full budgets'}); balanced = "
             "fraction of evaluation episodes that end balanced (`lagrange.tasks.balanced`); paper = CE-APG paper "
             "Table I (8 seeds, its own Brax v1 environments).", "",
             "| task | algorithm | return | balanced | env steps | wall-clock [s] | paper |",
             "|---|---|---|---|---|---|---|"]
    for name, algos in results["runs"].items():
        for algo, runs in algos.items():
            r = np.array([x["return"] for x in runs])
            b = np.mean([x["balanced_fraction"] for x in runs])
            st = np.mean([x["env_steps"] for x in runs])
            wc = np.mean([x["wall_clock"] for x in runs])
            pap = PAPER.get(algo, {}).get(name)
            pap = f"{pap[0]:g} +- {pap[1]:g}" if pap else "-"
            ret = f"{r.mean():.1f} +- {r.std():.1f}" if len(r) > 1 else f"{r.mean():.1f} (1 seed)"
            lines.append(f"| {name} | {LABELS[algo]} | {ret} | {b:.0%} | {st:.2e} | "
                         f"{wc:.0f} | {pap} |")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def plot_task(name, algos, path, quick):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for i, (algo, runs) in enumerate(algos.items()):
        color = f"C{i}"
        for j, run in enumerate(runs):
            if not run["curve"]:
                continue
            c = np.array(run["curve"])
            label = LABELS[algo] if j == 0 else None
            axes[0].plot(c[:, 0], c[:, 2], "o-", ms=3, color=color, alpha=0.8, label=label)
            axes[1].plot(c[:, 1], c[:, 2], "o-", ms=3, color=color, alpha=0.8, label=label)
        pap = PAPER.get(algo, {}).get(name)
        if pap and not quick:
            axes[0].axhline(pap[0], color=color, ls="--", lw=0.8)
    axes[0].set_xlabel("simulated environment steps")
    axes[1].set_xlabel("wall-clock seconds since start (compilation included)")
    for ax in axes:
        ax.set_yscale("symlog", linthresh=100.0)  # returns span 5000 down to -1e7 across algorithms
        ax.set_ylabel("deterministic evaluation return (symlog)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(f"{name}{' (QUICK smoke-scale budgets, not a comparison)' if quick else ''}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
