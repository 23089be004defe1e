"""SHAC, BPTT and Brax PPO on DFlex's Hopper, Cheetah, Ant and Humanoid: the SHAC paper's Figure 4 on two CPU cores.

    python -m benchmarks.locomotion --tasks cheetah --algos ppo --seeds 0   # train what is missing, then table+plots
    python -m benchmarks.locomotion --plot-only                            # table and plots from the saved runs
    python -m benchmarks.locomotion --tasks ant --algos ppo --ppo-steps 16384000   # a smaller PPO budget
    python -m benchmarks.locomotion --tasks ant --algos bptt --bptt-steps 8192000  # a smaller BPTT budget

Every algorithm trains on the same task objects (``Hopper.diffrl()``, ``Cheetah.diffrl()``, ``Ant.diffrl()``,
``Humanoid.diffrl()``; Brax PPO sees them through
:class:`lagrange.interop.brax.BraxEnv`, unchanged) and every final policy is evaluated deterministically on the same 16
random starts (``PRNGKey(10_000 + seed)``, 1000-step episodes), as the examples do.

- **SHAC**: ``examples/<task>_shac.py`` as a user runs them (``SHACConfig.hopper()``, ``cheetah()``, ``ant()``,
  ``humanoid()``: the authors' configs, 16.4M env steps on the hopper, 4.1M on the others), 20 evaluations along the
  way.
- **BPTT**: the SHAC paper's BPTT baseline as its authors ran it (``SHACConfig.bptt(task)``: no critic, windows of 128
  steps (hopper, cheetah; 8.2M env steps) or 1000 (ant, humanoid; 64M) in 32 environments), through the same driver.
- **Brax PPO**: Brax's PPO (``brax.training.agents.ppo``) with the SHAC authors' PPO settings
  (``examples/cfg/ppo/<task>.yaml``: 1024 environments x 32 steps per update, minibatches of 8192, 5 epochs, gamma
  0.99, GAE 0.95, lr 3e-4 with the adaptive-KL schedule at 0.008, clip 0.2, no entropy bonus, reward scale 0.01,
  gradient clip 1, value-loss weight 4 on rl_games' halved MSE, observation normalisation, ELU MLPs [128, 64, 32]
  for the policy and the value; the ant's 2048 environments and minibatches of 16384, the humanoid's minibatches of
  8192 and MLPs [256, 128, 64]) for 10x SHAC's env steps on the cheetah, the ant and the humanoid (41M) and SHAC's on
  the hopper (16.4M). What Brax's PPO does otherwise than rl_games': separate policy and value networks (rl_games shares
  a trunk), a tanh-normal policy (a clipped Gaussian), no value normalisation, no bounds loss. Its curve is Brax's own
  deterministic evaluator (16 environments); its wall-clock includes compilation and those evaluations. On the ant
  and the humanoid it trains in a child process with YNNPACK's fusions off (``lagrange.compile.YNN_OFF_FLAG`` in
  ``XLA_FLAGS``), as the library's own programs of a 3-D tree are compiled (8x faster on the humanoid).

SHAC and BPTT runs checkpoint every epoch and resume where a killed benchmark left them; a PPO run is redone from its
start if killed (Brax's trainer keeps no resumable state here). Each finished run is
``--runs-dir/<algo>_<task>_<seed>.json``; the table ``benchmarks/results/locomotion.{json,md}`` and the plots
``docs/img/locomotion_<task>.png`` (return against env steps and against wall-clock, every seed) are made from all of
them. The published runs in the JSON are written back to their run files on a fresh clone (``--plot-only``), and before
training those not asked for, so that a run of one task leaves the others' rows in the table.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import pathlib
import platform
import subprocess
import sys
import time

import jax
import numpy as np

from benchmarks._cli import markdown_table, read_runs, restore_runs, run_file, save_figure, subplots
from benchmarks.algorithms import BraxPolicy
from lagrange.compile import YNN_OFF_FLAG, compiler_options
from lagrange.tasks import Ant, Cheetah, Hopper, Humanoid, SNUHumanoid
from optim import SHACConfig, evaluate
from optim.checkpoint import write_json, write_text
from optim.locomotion_cli import locomotion_main

TASKS = {"hopper": Hopper.diffrl, "cheetah": Cheetah.diffrl, "ant": Ant.diffrl, "humanoid": Humanoid.diffrl,
         "snu_humanoid": SNUHumanoid.diffrl}
ALGORITHMS = ("shac", "bptt", "ppo")
LABELS = {"shac": "SHAC", "bptt": "BPTT", "ppo": "Brax PPO"}
CONFIGS = {"shac": {"hopper": SHACConfig.hopper(), "cheetah": SHACConfig.cheetah(), "ant": SHACConfig.ant(),
                    "humanoid": SHACConfig.humanoid(), "snu_humanoid": SHACConfig.snu_humanoid()},
           "bptt": {t: SHACConfig.bptt(t) for t in TASKS}}
ACTOR_UNITS = {"humanoid": (256, 128), "snu_humanoid": (512, 256)}  # the authors' actor_mlp; (128, 64, 32) else
PPO_STEPS = {"hopper": 16_384_000, "cheetah": 40_960_000, "ant": 40_960_000, "humanoid": 40_960_000,
             "snu_humanoid": 40_960_000}
PPO = dict(num_envs=1024, unroll_length=32, batch_size=256, num_minibatches=4, num_updates_per_batch=5,
           discounting=0.99, gae_lambda=0.95, learning_rate=3e-4, learning_rate_schedule="ADAPTIVE_KL",
           desired_kl=0.008, entropy_cost=0.0, clipping_epsilon=0.2, reward_scaling=0.01, max_grad_norm=1.0,
           vf_loss_coefficient=4.0, normalize_observations=True, num_evals=21)
PPO_TASK = {"ant": dict(num_envs=2048, batch_size=512), "humanoid": dict(hidden=(256, 128, 64)),  # their yaml's
            "snu_humanoid": dict(hidden=(512, 512, 256), num_updates_per_batch=6)}
# the AHAC paper's data for DFlex's tasks (1000-step episodes); none is published for the cheetah
ANCHORS = {"hopper": {"SHAC": 4800, "PPO": 4775}, "ant": {"SHAC": 7660, "PPO": 6605},
           "humanoid": {"SHAC": 8390, "PPO": 7293}, "snu_humanoid": {"SHAC": 6114, "PPO": 4246}}
EVAL_EPISODES = 16
ROOT = pathlib.Path(__file__).resolve().parent.parent


def run_differentiable(algo, task, seed, runs_dir, steps=None):
    """SHAC or BPTT through the examples' driver in ``runs_dir/<algo>_<task>_<seed>/`` (resumed if a checkpoint is
    there) for the config's epochs or, given ``steps``, as many epochs as reach that many env steps (the learning
    rates then decay over those epochs); returns the run record."""
    out = os.path.join(runs_dir, f"{algo}_{task}_{seed}")
    argv = ["--seed", str(seed), "--out", out, "--no-progress"]
    if os.path.exists(os.path.join(out, "checkpoint.eqx")):
        argv.append("--resume")
    cfg = CONFIGS[algo][task]
    if steps is not None:
        cfg = dataclasses.replace(cfg, iterations=-(-steps // cfg.env_steps_per_epoch()))
    r = locomotion_main(f"{LABELS[algo]} on {task}", out, TASKS[task], cfg, cfg, argv=argv,
                        actor_units=ACTOR_UNITS.get(task, (128, 64, 32)))
    curve = [(c["env_steps"], c["elapsed"], c["return"]) for c in r["curve"]]
    return {"return": r["return"], "return_std": r["return_std"], "env_steps": r["env_steps"],
            "wall_clock": r["wall_clock_s"], "curve": curve, "config": r["config"]}


def run_ppo(task_name, seed, steps=None):
    """Brax PPO on the task through the Brax adapter for ``steps`` env steps (default ``PPO_STEPS``); returns the
    run record."""
    from brax.training.agents.ppo import networks as ppo_networks
    from brax.training.agents.ppo.train import train as ppo_train
    from flax import linen

    from lagrange.interop.brax import BraxEnv, brax_training_compat

    task = TASKS[task_name]()
    settings = {**PPO, **PPO_TASK.get(task_name, {})}
    hidden = settings.pop("hidden", (128, 64, 32))
    nets = functools.partial(ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=hidden,
                             value_hidden_layer_sizes=hidden, activation=linen.elu)
    steps = steps or PPO_STEPS[task_name]
    curve, t0 = [], time.perf_counter()

    def progress(step, metrics):
        curve.append((float(step), time.perf_counter() - t0, float(metrics["eval/episode_reward"])))
        print(f"PPO {task_name} seed {seed}: {float(step):.3g} steps, {curve[-1][1]:.0f} s, "
              f"return {curve[-1][2]:.0f}", flush=True)

    with brax_training_compat():
        make_policy, params, _ = ppo_train(environment=BraxEnv(task), num_timesteps=steps,
                                           episode_length=task.horizon, seed=seed, deterministic_eval=True,
                                           num_eval_envs=EVAL_EPISODES, network_factory=nets, progress_fn=progress,
                                           **settings)
    wall = time.perf_counter() - t0
    pol = BraxPolicy(make_policy(params, deterministic=True))
    rets, _ = jax.device_get(jax.jit(lambda k: evaluate(task, pol, None, k, EVAL_EPISODES))(
        jax.random.PRNGKey(10_000 + seed)))
    return {"return": float(np.mean(rets)), "return_std": float(np.std(rets)), "env_steps": curve[-1][0],
            "wall_clock": wall, "curve": curve, "config": {**settings, "hidden": hidden,
                                                            "num_timesteps": steps}}


def _ppo_in_a_child(task, seed, runs_dir, steps):
    """Brax PPO on a 3-D task in a fresh interpreter with ``XLA_FLAGS`` holding ``YNN_OFF_FLAG``: Brax's trainer jits
    its own programs, which ``lg.compiler_options`` cannot reach, and the flag must be set before JAX starts. The child
    writes the run file."""
    flags = f"{os.environ.get('XLA_FLAGS', '')} {YNN_OFF_FLAG}".strip()
    argv = [sys.executable, "-m", "benchmarks.locomotion", "--tasks", task, "--algos", "ppo", "--seeds", str(seed),
            "--runs-dir", str(pathlib.Path(runs_dir).resolve())] + (["--ppo-steps", str(steps)] if steps else [])
    subprocess.run(argv, env={**os.environ, "XLA_FLAGS": flags}, cwd=ROOT, check=True)


def train_one(algo, task, seed, runs_dir, ppo_steps=None, bptt_steps=None):
    """Train (or resume) one run and write its record ``runs_dir/<algo>_<task>_<seed>.json``; ``ppo_steps`` and
    ``bptt_steps`` replace those algorithms' default budgets."""
    if (algo == "ppo" and compiler_options(TASKS[task]().chain) is not None
            and YNN_OFF_FLAG not in os.environ.get("XLA_FLAGS", "")):
        _ppo_in_a_child(task, seed, runs_dir, ppo_steps)
        return json.loads(run_file(runs_dir, algo, task, seed).read_text())
    load0, cpu0 = os.getloadavg(), time.process_time()
    if algo == "ppo":
        r = run_ppo(task, seed, ppo_steps)
    else:
        r = run_differentiable(algo, task, seed, runs_dir, bptt_steps if algo == "bptt" else None)
    record = {"algo": algo, "task": task, "seed": seed, **r, "cpu_seconds": time.process_time() - cpu0,
              "loadavg_start": list(load0), "loadavg_end": list(os.getloadavg())}
    write_json(run_file(runs_dir, algo, task, seed), record)
    return record


def load_runs(runs_dir):
    """``{task: {algo: [record, ...]}}`` from the run files, seeds in order."""
    found = read_runs(runs_dir)
    runs: dict = {}
    for task in TASKS:
        for algo in ALGORITHMS:
            rs = sorted((r for r in found if r["task"] == task and r["algo"] == algo), key=lambda r: r["seed"])
            if rs:
                runs.setdefault(task, {})[algo] = rs
    return runs


def write_table(runs, out_dir):
    rows = []
    for task, algos in runs.items():
        for algo, rs in algos.items():
            rets = [r["return"] for r in rs]
            rows.append({"task": task, "algorithm": LABELS[algo], "seeds": len(rs),
                         "return": f"{np.mean(rets):.0f} +- {np.std(rets):.0f}",
                         "per seed": ", ".join(f"{x:.0f}" for x in rets),
                         "best evaluation on the way": ", ".join(f"{max(c[2] for c in r['curve']):.0f}" for r in rs),
                         "env steps": f"{np.mean([r['env_steps'] for r in rs]):.3g}",
                         "wall-clock [s]": f"{np.mean([r['wall_clock'] for r in rs]):.0f}",
                         "published": str(ANCHORS.get(task, {}).get(LABELS[algo].split()[-1], "-"))})
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, shared"
    md = (f"# SHAC, BPTT and Brax PPO on DFlex's locomotion tasks\n\n{machine}. Regenerate: "
          "`python -m benchmarks.locomotion --plot-only`.\n\n"
          + markdown_table(rows, list(rows[0]) if rows else []) + "\n")
    write_text(os.path.join(out_dir, "locomotion.md"), md)
    write_json(os.path.join(out_dir, "locomotion.json"), {"machine": machine, "rows": rows, "runs": runs})


def plot_task(task, algos, path):
    fig, axes = subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for algo, rs in algos.items():
        for j, r in enumerate(rs):
            c = np.asarray(r["curve"], float).reshape(-1, 3)
            for ax, col in zip(axes, (0, 1)):
                ax.plot(c[:, col], c[:, 2], color=f"C{ALGORITHMS.index(algo)}", lw=1.2, alpha=0.85,
                        label=f"{LABELS[algo]} ({len(rs)} seed{'s' * (len(rs) > 1)})" if j == 0 else None)
    anchors = ANCHORS.get(task, {})
    for ax in axes:
        for value in anchors.values():
            ax.axhline(value, color="k", ls="--", lw=0.8)
    if anchors:
        axes[0].annotate("published: " + ", ".join(f"{k} {v}" for k, v in anchors.items()),
                         (0, max(anchors.values())), fontsize=7, va="bottom")
    axes[0].set_xlabel("simulated environment steps")
    axes[1].set_xlabel("wall-clock on 2 shared CPU cores [s]")
    axes[0].set_ylabel("return (deterministic policy)")
    axes[0].legend(fontsize=8, loc="lower right")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"{task}: SHAC, BPTT and Brax PPO on the same exact dynamics")
    save_figure(fig, path, dpi=100)


def published_runs(saved: dict) -> list[dict]:
    """The run records of the published ``locomotion.json``."""
    return [r for algos in saved["runs"].values() for rs in algos.values() for r in rs]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    p.add_argument("--algos", nargs="+", default=list(ALGORITHMS), choices=ALGORITHMS)
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    p.add_argument("--runs-dir", default="runs/locomotion", help="per-run folders and records")
    p.add_argument("--plot-only", action="store_true", help="only the table and plots from the saved runs")
    p.add_argument("--ppo-steps", type=int, default=None,
                   help="Brax PPO's env steps (default: 10x SHAC's, the hopper's 1x; see PPO_STEPS)")
    p.add_argument("--bptt-steps", type=int, default=None,
                   help="BPTT's env steps, rounded up to whole epochs (default: the authors' 2000 epochs)")
    args = p.parse_args(argv)
    for flag in ("ppo_steps", "bptt_steps"):
        if getattr(args, flag) is not None and getattr(args, flag) < 1:
            p.error(f"--{flag.replace('_', '-')} must be >= 1, got {getattr(args, flag)}")
    results = ROOT / "benchmarks" / "results"
    # the published runs not asked for keep their rows (all of them on a fresh clone, or with --plot-only): a run of
    # one task rewrites the table with every run
    asked = set() if args.plot_only else {(a, t, s) for t in args.tasks for a in args.algos for s in args.seeds}
    restore_runs(args.runs_dir, results / "locomotion.json", published_runs,
                 keep=lambda r: (r["algo"], r["task"], r["seed"]) not in asked)
    if not args.plot_only:
        for task in args.tasks:
            for algo in args.algos:
                for seed in args.seeds:
                    if not run_file(args.runs_dir, algo, task, seed).exists():
                        train_one(algo, task, seed, args.runs_dir, args.ppo_steps, args.bptt_steps)
    runs = load_runs(args.runs_dir)
    write_table(runs, results)
    for task, algos in runs.items():
        plot_task(task, algos, ROOT / "docs" / "img" / f"locomotion_{task}.png")
    print((results / "locomotion.md").read_text())


if __name__ == "__main__":
    main()
