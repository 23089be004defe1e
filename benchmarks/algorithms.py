"""CE-APG, SHAC, Brax PPO, Brax SAC and Brax APG on the paper's three tasks, on the same dynamics.

    python -m benchmarks.algorithms --quick                          # smoke-scale budgets, seed 0 (runs/benchmarks/)
    python -m benchmarks.algorithms --budget laptop --tasks acrobot --algos shac ppo sac brax_apg --seeds 0
    python -m benchmarks.algorithms --budget laptop --algos ce_apg --ce-apg-from runs/paper_tables/laptop
    python -m benchmarks.algorithms --budget laptop --plot-only      # table and plots from the saved runs
    python -m benchmarks.algorithms --budget laptop --bodies brax_v1 --tasks acrobot   # on the authors' bodies

Every algorithm trains on the same task objects (``lagrange.tasks.PAPER_TASKS[name].rods()``; the Brax trainers see
them through :class:`lagrange.interop.brax.BraxEnv`, unchanged), and each final policy is evaluated deterministically
here on the same 16 random starts (``PRNGKey(10_000 + seed)``) with the task's 500-step return and
:func:`lagrange.tasks.balanced`. Learning curves: deterministic evaluation returns against simulated env steps and
against wall-clock seconds since the run's start (compilation and evaluation included); Brax's from Brax's own
evaluator (``deterministic_eval=True``) on its own random starts. ``--bodies brax_v1`` puts every algorithm on the
authors' Brax v1 bodies (``Acrobot.brax_v1()`` etc., those of the paper's Table I); its files get a ``_brax_v1``
suffix.

Budgets (``--budget``): ``laptop`` (:data:`LAPTOP`), what two shared CPU cores afford: SAC and Brax APG with the
hyperparameters and budgets of the CE-APG paper's appendix IX-C, PPO with its hyperparameters but 1.2e6 of its 8e7
steps (:data:`LAPTOP_CUTS`), SHAC the SHAC authors' cartpole config (``SHACConfig()``, 1e6 steps), CE-APG this
project's laptop protocol (``CEAPGConfig.laptop(task)``, the ``laptop`` budget of ``benchmarks/paper_tables.py``);
``--ce-apg-from DIR`` reads CE-APG's results from the ``ce_apg_<task>_<seed>.json`` files that
``benchmarks/paper_tables.py`` writes instead of training (its curve is then the best candidate's training fitness
from the checkpoint beside it, if any). ``quick`` (:data:`QUICK`, also ``--quick``): a smoke test of every budget,
whose numbers compare nothing.

Each (algorithm, task, seed) run writes its result, with its process CPU seconds and the load average, as soon as it
finishes to ``--runs-dir/<budget>/<algo>_<task>_<seed>.json`` and is skipped when that file exists, so a killed
benchmark resumes (``--force`` redoes the selected runs). The table and plots are made from every run file of the
budget: ``benchmarks/results/algorithms_laptop[_brax_v1].{json,md}`` and
``docs/img/algorithms_laptop[_brax_v1]_<task>.png`` (``--quick``: ``algorithms_quick*`` under ``runs/benchmarks/``,
not published); ``--plot-only`` remakes them from the saved runs (on a fresh clone, restored from the JSON).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import os
import pathlib
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks._cli import (add_bodies_flag, bodies_marker, bodies_suffix, marked_bodies, outputs, paper_task,
                             read_runs, restore_runs, run_file, save_figure, subplots)
from benchmarks.paper_tables import EVAL_EPISODES, WIDTH, evaluate_final
from optim import CEAPGConfig, SHACConfig
from optim.checkpoint import FORMAT as CHECKPOINT_FORMAT, write_json, write_text
from policies import GRUPolicy
from policies.actor_critic import Actor

TASKS = ("acrobot", "cartpole", "double_cartpole")
ALGORITHMS = ("ce_apg", "shac", "ppo", "sac", "brax_apg")
HORIZON = 500

# Paper Table I (mean, std over 8 seeds); the CE-APG paper calls the cartpole "Pendulum" and the
# double cartpole "Double Pendulum".
PAPER = {
    "ce_apg": {"cartpole": (-355, 10), "acrobot": (3053, 458), "double_cartpole": (4295, 75)},
    "ppo": {"cartpole": (-464, 223), "acrobot": (405, 927), "double_cartpole": (4249, 549)},
    "sac": {"cartpole": (-2274, 1000), "acrobot": (359, 159), "double_cartpole": (-3.9e5, 4.9e6)},
    "brax_apg": {"cartpole": (-3485, 819), "acrobot": (1949, 814), "double_cartpole": (-1982, 4056)},
}

# LAPTOP cuts, measured on the acrobot with two CPU cores shared by four to six training processes (this
# process got 7-30 % of one core): a PPO update of the paper's geometry (512 envs x 50 steps x 256 x 32 =
# 409,600 steps, then 8 epochs x 32 minibatches through Brax's 5 x 256 value network) costs ~40
# CPU-seconds (~250 s of wall-clock there); 1,000 SAC steps (64 envs, one gradient step each) ~5
# CPU-seconds; a Brax APG update (24 x 500 steps) ~0.01 CPU-seconds after ~25 CPU-seconds of compilation.
# SAC and Brax APG keep the paper's budgets; PPO is cut to keep a run near 10 minutes of that wall-clock.
PPO_LAPTOP_STEPS = 1_228_800  # 3 PPO updates of 409,600 steps (the paper: 8e7, 195 updates)

# the hyperparameters of the CE-APG paper's appendix IX-C, in both budgets
PPO_HP = dict(unroll_length=50, num_updates_per_batch=8, discounting=0.99, learning_rate=3e-4, entropy_cost=1e-3,
              normalize_observations=True)
SAC_HP = dict(num_envs=64, batch_size=128, discounting=0.95, learning_rate=1e-3, normalize_observations=True)
BRAX_APG_HP = dict(num_envs=24, learning_rate=5e-4, horizon_length=HORIZON, normalize_observations=True)
QUICK = {
    "ce_apg": dict(num_candidates=4, num_elites=2, iterations=3, apg_steps=5, episodes=2),
    "shac": dict(num_envs=32, iterations=40),
    "ppo": dict(num_timesteps=60_000, num_envs=64, batch_size=64, num_minibatches=4, **PPO_HP, num_evals=3),
    "sac": dict(num_timesteps=30_000, **SAC_HP, num_evals=3),
    "brax_apg": dict(env_steps=72_000, **BRAX_APG_HP, num_evals=3),
}
LAPTOP = {
    # this project's laptop protocol (benchmarks/paper_tables.py --budget laptop): 1.8e8 steps, hours here
    "ce_apg": dict(preset="laptop"),  # CEAPGConfig.laptop(task), (sin, cos) observations on the acrobot
    "shac": {},  # SHACConfig defaults (the SHAC authors' config) and Actor.for_task(task), the task's 500-step episodes
    # the paper's budgets but PPO's, cut from its 8e7 steps
    "ppo": dict(num_timesteps=PPO_LAPTOP_STEPS, num_envs=512, batch_size=256, num_minibatches=32, **PPO_HP,
                num_evals=4),
    "sac": dict(num_timesteps=2_000_000, **SAC_HP, num_evals=20),
    "brax_apg": dict(env_steps=10_000_000, **BRAX_APG_HP, num_evals=20),
}
LAPTOP_CUTS = {
    "ce_apg": "CEAPGConfig.laptop(task): 1.8e8 (acrobot), 7.2e7 (cartpole), 9e7 (double cartpole) of the paper's "
              "~1e9 env steps (fewer elites, APG steps, episodes and iterations; lr 1e-2 -> 1e-4 instead of "
              "1e-3 -> 1e-6; (sin, cos) observations on the acrobot)",
    "ppo": f"{PPO_LAPTOP_STEPS:.3g} of the paper's 8e7 env steps, 3 updates (same batch geometry and "
           "hyperparameters)",
}

BUDGETS = {"quick": QUICK, "laptop": LAPTOP}


class BraxPolicy:
    """A Brax inference function ``f(obs, key) -> (action, extras)`` with the rollout interface of
    :func:`optim.episode` (stateless; normalisation is inside the Brax parameters)."""

    def __init__(self, fn):
        self.fn = fn

    def initial_state(self):
        return jnp.zeros(0, jnp.float32)

    def __call__(self, obs, hidden, reset=False):
        action, _ = self.fn(obs.astype(jnp.float32), jax.random.PRNGKey(0))
        return action, hidden


def _evaluate(task, policy, normalizer, seed):
    rets, bal = jax.device_get(evaluate_final(task, policy, normalizer, seed))
    return np.asarray(rets, float), np.asarray(bal, bool)


# one run per algorithm: returns (final returns, balanced flags, curve, env_steps, wall_clock)


def run_ce_apg(name, seed, budget, bodies="rods"):
    budget = dict(budget)
    if budget.pop("preset", "paper") == "laptop":  # this project's laptop protocol: (sin, cos) acrobot observations
        cfg = CEAPGConfig.laptop(name, **budget)
        task = paper_task(name, bodies, **({"trig": True} if name == "acrobot" else {}))
    else:
        cfg, task = CEAPGConfig.paper(**budget), paper_task(name, bodies)
    trainer = cfg.make_trainer(task, GRUPolicy.for_task(task, WIDTH[name]))
    return _train(trainer, cfg.iterations, cfg.env_steps_per_iteration(task.horizon), 1, seed, "best")


def run_shac(name, seed, budget, bodies="rods"):
    cfg, task = SHACConfig(**budget), paper_task(name, bodies)
    trainer = cfg.make_trainer(task, Actor.for_task(task))
    return _train(trainer, cfg.iterations, cfg.env_steps_per_epoch(), max(1, cfg.iterations // 10), seed)


def _train(trainer, iterations, steps_per_iteration, every, seed, *which):
    """``iterations`` updates of ``trainer`` from ``PRNGKey(seed)``, its policy (``trainer.policy(state, *which)``)
    evaluated after every ``every``-th update and the last."""
    t0 = time.perf_counter()
    state = trainer.init(jax.random.PRNGKey(seed))
    curve = []
    for i in range(1, iterations + 1):
        state, _ = trainer.update(state)
        if i % every == 0 or i == iterations:
            rets, _ = _evaluate(trainer.task, *trainer.policy(state, *which), seed)
            curve.append((float(i * steps_per_iteration), time.perf_counter() - t0, float(rets.mean())))
    rets, bal = _evaluate(trainer.task, *trainer.policy(state, *which), seed)
    return rets, bal, curve, float(iterations * steps_per_iteration), time.perf_counter() - t0


class Diverged(Exception):
    """A Brax trainer's final ``pmap.assert_is_replicated(training_state)`` failed, which on one device
    happens exactly when the training state holds a NaN; ``curve`` is the learning curve up to then."""

    def __init__(self, curve):
        super().__init__("non-finite training state (Brax's replication check failed)")
        self.curve = curve


def _run_brax(kind, name, seed, budget, bodies="rods"):
    from lagrange.interop.brax import BraxEnv, brax_training_compat

    task = paper_task(name, bodies)
    env = BraxEnv(task)
    budget = dict(budget)
    curve = []
    t0 = time.perf_counter()
    fn = importlib.import_module(f"brax.training.agents.{kind.removeprefix('brax_')}.train").train
    per_eval, steps_total = 1, budget.get("num_timesteps")  # env steps per step Brax reports; in all
    if kind == "brax_apg":
        per_update = budget["num_envs"] * budget["horizon_length"]
        updates = max(1, int(budget.pop("env_steps")) // per_update)
        budget["policy_updates"] = updates
        # Brax APG runs round(updates / (num_evals - 1)) updates between evaluations and reports the
        # evaluation index as its step; convert to simulated steps.
        per_eval = int(round(updates / max(budget["num_evals"] - 1, 1))) * per_update
        steps_total = per_eval * max(budget["num_evals"] - 1, 1)
    progress = lambda step, m: curve.append((float(step) * per_eval, time.perf_counter() - t0,  # noqa: E731
                                             float(m["eval/episode_reward"])))
    try:
        with brax_training_compat():
            make_policy, params, _ = fn(environment=env, episode_length=HORIZON, seed=seed,
                                        deterministic_eval=True, num_eval_envs=16, **budget, progress_fn=progress)
    except AssertionError as e:
        raise Diverged(curve) from e
    rets, bal = _evaluate(task, BraxPolicy(make_policy(params, deterministic=True)), None, seed)
    steps = curve[-1][0] if curve and kind != "brax_apg" else float(steps_total)
    return rets, bal, curve, steps, time.perf_counter() - t0


RUNNERS = {"ce_apg": run_ce_apg, "shac": run_shac}
RUNNERS |= {kind: functools.partial(_run_brax, kind) for kind in ("ppo", "sac", "brax_apg")}
LABELS = {"ce_apg": "CE-APG", "shac": "SHAC", "ppo": "Brax PPO", "sac": "Brax SAC", "brax_apg": "Brax APG"}


def train_one(algo, task, seed, budget, budget_name, bodies="rods"):
    """Train and evaluate one (algorithm, task on ``bodies``, seed); returns the run's result dict."""
    load0, cpu0, t0 = os.getloadavg(), time.process_time(), time.perf_counter()
    try:
        rets, bal, curve, steps, wall = RUNNERS[algo](task, seed, budget, bodies)
        result = {"return": float(rets.mean()), "returns": rets.tolist(), "balanced_fraction": float(bal.mean()),
                  "balanced": bool(bal.all()), "env_steps": float(steps), "wall_clock": float(wall)}
    except Diverged as e:  # recorded as a failed seed, not retried
        curve = e.curve
        result = {"failed": f"diverged: {e}; last evaluation return {curve[-1][2] if curve else None}",
                  "return": None, "returns": None, "balanced_fraction": 0.0, "balanced": False, "env_steps": None,
                  "wall_clock": time.perf_counter() - t0}
    return {"algo": algo, "task": task, "seed": seed, "budget": budget_name, "source": "trained", **result,
            "cpu_seconds": time.process_time() - cpu0, "loadavg_start": list(load0),
            "loadavg_end": list(os.getloadavg()), "config": budget, "curve": curve, "curve_kind": "evaluation",
            **bodies_marker(bodies)}


def import_ce_apg(task, seed, src_dir, bodies="rods"):
    """CE-APG's result for (task, seed) from ``benchmarks/paper_tables.py``'s ``ce_apg_<task>_<seed>.json``
    in ``src_dir`` (None when absent). Its curve is the best candidate's training fitness per iteration
    from the checkpoint header (``.eqx`` beside it), when there is one; it has no per-episode returns.
    Exits if the file's run was trained on other bodies than ``bodies``."""
    path = run_file(src_dir, "ce_apg", task, seed)
    if not path.exists():
        return None
    r = json.loads(path.read_text())
    trained_on = marked_bodies(r.get("config") or {})
    if trained_on != bodies:
        raise SystemExit(f"{path} was trained on bodies={trained_on!r}, not --bodies {bodies}: pick the paper_tables "
                         f"folder of those bodies (e.g. runs/paper_tables/laptop_braxv1 for brax_v1)")
    curve, kind = [], None
    if path.with_suffix(".eqx").exists():
        hist = _checkpoint_history(path.with_suffix(".eqx"))
        curve = [(h["env_steps"], h["elapsed"], h["best_return"]) for h in hist if "best_return" in h]
        kind = "training fitness of the best candidate"
    return {"algo": "ce_apg", "task": task, "seed": seed, "budget": r.get("budget"), "source": str(path),
            "return": float(r["return"]), "returns": None, "balanced_fraction": r.get("balanced_fraction"),
            "balanced": bool(r["balanced"]), "env_steps": float(r["env_steps"]),
            "wall_clock": float(r["wall_clock_seconds"]), "cpu_seconds": None, "config": r.get("config"),
            "curve": curve, "curve_kind": kind, **bodies_marker(bodies)}


def _checkpoint_history(path) -> list:
    """The ``history`` in the JSON header line of a checkpoint, of any format version: the runs of
    ``benchmarks/paper_tables.py`` from before ``optim.train`` (version 1) record it as today's do."""
    with open(path, "rb") as f:
        head = json.loads(f.readline())
    if not isinstance(head, dict) or head.get("format") != CHECKPOINT_FORMAT:
        raise SystemExit(f"{path} is not a lagrange checkpoint")
    return head.get("history", [])


def _runs(results) -> list:
    """Every run of a results dict (``{"runs": {task: {algo: [run, ...]}}}``), in its order."""
    return [r for algos in results.get("runs", {}).values() for rs in algos.values() for r in rs]


def load_runs(runs_dir):
    """Every run file in ``runs_dir`` as ``{task: {algo: [run, ...]}}`` (tasks, algorithms, seeds in order)."""
    runs: dict = {}
    for r in sorted(read_runs(runs_dir), key=lambda r: (TASKS.index(r["task"]), ALGORITHMS.index(r["algo"]),
                                                         r["seed"])):
        runs.setdefault(r["task"], {}).setdefault(r["algo"], []).append(r)
    return runs


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--budget", choices=tuple(BUDGETS), default=None, help="quick | laptop (default laptop)")
    p.add_argument("--quick", action="store_true", help="same as --budget quick")
    p.add_argument("--seeds", nargs="+", type=int, default=None,
                   help="seeds to run (default: 0 with the quick budget, else 0..7)")
    p.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    p.add_argument("--algos", "--algorithms", dest="algos", nargs="+", default=list(ALGORITHMS), choices=ALGORITHMS)
    p.add_argument("--ce-apg-from", default=None, metavar="DIR",
                   help="take CE-APG from DIR/ce_apg_<task>_<seed>.json (benchmarks/paper_tables.py) instead of "
                        "training it")
    p.add_argument("--runs-dir", default="runs/algorithms", help="per-run result files go to RUNS_DIR/<budget>/")
    p.add_argument("--force", action="store_true", help="redo the selected runs even where a result file exists")
    p.add_argument("--out", default=None, help="folder of the table and plots (default: benchmarks/results for the "
                                               "table, docs/img for the plots; runs/benchmarks with --quick)")
    p.add_argument("--plot-only", action="store_true", help="only redo the table and plots from the saved runs")
    add_bodies_flag(p)
    args = p.parse_args(argv)
    if args.quick and args.budget not in (None, "quick"):
        raise SystemExit(f"--quick contradicts --budget {args.budget}")
    budget_name = "quick" if args.quick else (args.budget or "laptop")
    seeds = args.seeds if args.seeds is not None else ([0] if budget_name == "quick" else list(range(8)))
    if any(s < 0 for s in seeds):
        raise SystemExit(f"--seeds must be >= 0, got {seeds}")
    budgets = BUDGETS[budget_name]
    suffix = bodies_suffix(args.bodies)
    tag = f"algorithms_{budget_name}{suffix}"
    runs_dir = os.path.join(args.runs_dir, budget_name + suffix)
    out, img = (args.out, args.out) if args.out else outputs(budget_name == "quick")
    json_path = pathlib.Path(out, f"{tag}.json")
    restore_runs(runs_dir, json_path, _runs)
    for task in [] if args.plot_only else args.tasks:
        for algo in args.algos:
            for seed in seeds:
                path, what = run_file(runs_dir, algo, task, seed), f"{task:16s} {LABELS[algo]:9s} seed {seed}"
                if algo == "ce_apg" and args.ce_apg_from:
                    run = import_ce_apg(task, seed, args.ce_apg_from, args.bodies)
                    if run is None:
                        print(f"{what}: no result in {args.ce_apg_from}, skipped")
                        continue
                elif path.exists() and not args.force:
                    print(f"{what}: done already ({path})")
                    continue
                else:
                    print(f"{what} ...", flush=True)
                    run = train_one(algo, task, seed, dict(budgets[algo]), budget_name, args.bodies)
                write_json(path, run)
                print(f"{what}: FAILED {run['failed']}" if run.get("failed") else f"{what}: return "
                      f"{run['return']:.1f}, balanced {run['balanced']}, {run['env_steps']:.2e} steps, "
                      f"{run['wall_clock']:.0f} s", flush=True)
    runs = load_runs(runs_dir)
    results = {"meta": {"budget": budget_name, "quick": budget_name == "quick", **bodies_marker(args.bodies),
                        "seeds": sorted({r["seed"] for r in _runs({"runs": runs})}),
                        "budgets": {a: budgets[a] for a in ALGORITHMS},
                        "cuts": LAPTOP_CUTS if budget_name == "laptop" else {},
                        "eval_episodes": EVAL_EPISODES, "jax": jax.__version__, "devices": str(jax.devices()),
                        "machine": platform.platform(), "cpus": os.cpu_count(), "runs_dir": runs_dir},
               "runs": runs}
    write_json(json_path, results)
    write_table(results, os.path.join(out, f"{tag}.md"))
    for name in results["runs"]:
        plot_task(name, results["runs"][name], os.path.join(img, f"{tag}_{name}.png"), budget_name, args.bodies)
    return results


def _cpu_share(runs):
    shares = [r["cpu_seconds"] / r["wall_clock"] for r in runs if r.get("cpu_seconds") and r["wall_clock"] > 0]
    return f"{np.mean(shares):.2f}" if shares else "-"


def _bodies_sentence(results):
    bodies = marked_bodies(results["meta"])
    return "" if bodies == "rods" else (f" Every run on the tasks' `{bodies}` bodies (`Acrobot.{bodies}()` etc., "
                                        "`lagrange.tasks`), not this library's rods.")


def write_table(results, path):
    budget = results["meta"]["budget"]
    what = {"quick": "QUICK smoke-scale budgets", "laptop": "LAPTOP budgets, cut from the paper's where noted"}[budget]
    lines = [f"Final deterministic return over {EVAL_EPISODES} random starts, mean +- std over seeds ({what}); "
             "balanced episodes = fraction of evaluation episodes that end balanced (`lagrange.tasks.balanced`), "
             "balanced seeds = fraction of seeds whose every evaluation episode does; CPU share = process CPU "
             f"seconds / wall-clock seconds ({results['meta'].get('cpus')} cores, shared with other jobs: the "
             "wall-clock is inflated where it is below the cores' count); paper = CE-APG paper Table I "
             "(8 seeds, its own Brax v1 environments)."
             + _bodies_sentence(results), "",
             "| task | algorithm | return | seeds | balanced episodes | balanced seeds | env steps | "
             "wall-clock [s] | CPU share | paper |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, algos in results["runs"].items():
        for algo, all_runs in algos.items():
            runs = [x for x in all_runs if not x.get("failed")]
            n_failed = len(all_runs) - len(runs)
            if not runs:
                lines.append(f"| {name} | {LABELS[algo]} | all failed | {len(all_runs)} ({n_failed} failed) | "
                             f"- | 0% | - | - | - | - |")
                continue
            r = np.array([x["return"] for x in runs])
            be = [x["balanced_fraction"] for x in runs if x.get("balanced_fraction") is not None]
            be = f"{np.mean(be):.0%}" if be else "-"
            bs = [x["balanced"] for x in all_runs if x.get("balanced") is not None]  # failed: not balanced
            bs = f"{np.mean(bs):.0%}" if bs else "-"
            st = np.mean([x["env_steps"] for x in runs])
            wc = np.mean([x["wall_clock"] for x in runs])
            pap = PAPER.get(algo, {}).get(name)
            pap = f"{pap[0]:g} +- {pap[1]:g}" if pap else "-"
            ret = f"{r.mean():.1f} +- {r.std():.1f}" if len(r) > 1 else f"{r.mean():.1f}"
            seeds = f"{len(all_runs)}" + (f" ({n_failed} failed)" if n_failed else "")
            lines.append(f"| {name} | {LABELS[algo]} | {ret} | {seeds} | {be} | {bs} | {st:.2e} | {wc:.0f} | "
                         f"{_cpu_share(runs)} | {pap} |")
    failed = [x for x in _runs(results) if x.get("failed")]
    if failed:
        groups: dict = {}
        for x in failed:
            groups.setdefault((x["algo"], x["task"], x["failed"]), []).append(str(x["seed"]))
        lines += ["", "Failed seeds (return, env steps and wall-clock are over the other seeds; they count as not "
                  "balanced): " + "; ".join(f"{LABELS[a]} {t} seed(s) {', '.join(ss)}: {why}"
                                            for (a, t, why), ss in groups.items()) + "."]
    present = {a for algos in results["runs"].values() for a in algos}
    trained = {a for algos in results["runs"].values() for a, rs in algos.items()
               if any(x.get("source", "trained") == "trained" for x in rs)}
    cuts = {a: c for a, c in (results["meta"].get("cuts") or {}).items() if a in present and a in trained}
    if cuts:
        lines += [""] + [f"Cut from the paper: {LABELS[a]} {c}." for a, c in cuts.items()]
    imported = [x for x in _runs(results) if x.get("source") not in (None, "trained")]
    if imported:
        keys = ("num_candidates", "num_elites", "iterations", "apg_steps", "episodes", "lr_start", "lr_end",
                "init_std", "width", "trig_observation")
        cfgs = sorted({json.dumps({k: (x.get("config") or {}).get(k) for k in keys}) for x in imported})
        lines += ["", f"CE-APG rows read from `benchmarks/paper_tables.py` results ({len(imported)} file(s), e.g. "
                  f"`{imported[0]['source']}`), not trained by this script: same 16 evaluation starts, final "
                  "policy `trainer.policy(state)`; balanced episodes as recorded there. Their config(s): "
                  + "; ".join(f"`{c}`" for c in cfgs) + "."]
    write_text(path, "\n".join(lines) + "\n")
    print("\n".join(lines))


def plot_task(name, algos, path, budget, bodies="rods"):
    quick = budget == "quick"
    fig, axes = subplots(1, 2, figsize=(11, 4))
    for algo, runs in algos.items():
        color = f"C{ALGORITHMS.index(algo)}"  # one colour per algorithm across the tasks' plots
        for j, run in enumerate([x for x in runs if not x.get("failed")]):
            if not run["curve"]:  # e.g. an imported CE-APG result: its final evaluation only
                for ax, x in zip(axes, (run["env_steps"], run["wall_clock"])):
                    ax.plot([x], [run["return"]], "x", ms=7, color=color,
                            label=f"{LABELS[algo]} (final only)" if j == 0 else None)
                continue
            c = np.array(run["curve"], float)
            fitness = run.get("curve_kind") not in (None, "evaluation")
            label = (LABELS[algo] + (" (training fitness)" if fitness else "")) if j == 0 else None
            style = dict(ls="--" if fitness else "-", marker="." if fitness else "o", ms=3, color=color, alpha=0.8,
                         label=label)
            for ax, x in zip(axes, (c[:, 0], c[:, 1])):
                keep = x > 0  # log axes: the step-0 evaluation has no place on them
                ax.plot(x[keep], c[keep, 2], **style)
        pap = PAPER.get(algo, {}).get(name)
        if pap and not quick:
            axes[0].axhline(pap[0], color=color, ls=":", lw=0.8)
    axes[0].set_xlabel("simulated environment steps")
    axes[0].set_xscale("log")
    axes[1].set_xlabel("wall-clock seconds since start (compilation included; shared CPU)")
    axes[1].set_xscale("log")
    for ax in axes:
        ax.set_yscale("symlog", linthresh=100.0)  # returns span 5000 down to -1e7 across algorithms
        ax.set_ylabel("deterministic evaluation return (symlog)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    note = {"quick": " (QUICK smoke-scale budgets, not a comparison)",
            "laptop": " (LAPTOP budgets; dotted: paper Table I)"}[budget]
    fig.suptitle(f"{name}{'' if bodies == 'rods' else f' on the {bodies} bodies'}{note}")
    save_figure(fig, pathlib.Path(path), dpi=110)


if __name__ == "__main__":
    main()
