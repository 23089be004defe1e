"""The paper's Tables I and II, with ours beside them: CE-APG, PAPG, CEM and APG on the three tasks.

    python benchmarks/paper_tables.py --budget laptop --algos ce_apg   # Table I on the rods (the examples' defaults)
    python benchmarks/paper_tables.py --algos ce_apg --variant braxv1 --set bodies=brax_v1   # on the Brax v1 bodies
    python benchmarks/paper_tables.py --budget laptop   # every algorithm: Table II's PAPG, CEM and APG too (hours)
    python benchmarks/paper_tables.py --budget paper   # the authors' protocol (about 1e9 env steps per CE-APG run)
    python benchmarks/paper_tables.py --budget smoke --seeds 0   # a pipeline check (numbers meaningless; runs/)

The published acrobot variants (``--tasks acrobot --algos ce_apg --set max_grad_norm=none`` and the following: they
were trained before the acrobot's preset clipped its gradients):

    --variant ep1 --set episodes=1                                  # one episode per APG step
    --variant braxv1ep1 --set bodies=brax_v1 --set episodes=1
    --variant braxv1warmup --set bodies=brax_v1 \
        --set warmup_horizons=300,400 --set warmup_iterations=20 --set warmup_upright=0   # the horizon curriculum
    --variant braxv1warmupep1 --set bodies=brax_v1 --set episodes=1 \
        --set warmup_horizons=300,400 --set warmup_iterations=20 --set warmup_upright=0

For every (algorithm, task, seed) it trains, evaluates the final deterministic policy on 16 fixed random starts and
records the mean return, whether every evaluation episode balanced, env steps and wall-clock seconds. Runs are
checkpointed under ``--out`` and skipped when their result exists, so a killed benchmark resumes; a result trained
with another config than the selected one stops the script, naming the changed fields. From every finished run of the
budget it writes ``--out/<budget>/{results.json,tables.md}`` (mean +- std over seeds, the fraction of seeds that
balance, the paper's numbers beside ours) and the same as ``benchmarks/results/paper_tables_<budget>_*`` (``--budget
smoke``: under ``runs/benchmarks/``, not published). ``--set FIELD=VALUE`` (repeatable) changes a field of every
selected algorithm's config, or of the task and policy it trains (``bodies``, ``horizon``, ``policy``, ``width``,
``trig_observation``: :class:`Protocol`); such runs need a ``--variant NAME`` and are kept apart, in
``--out/<budget>_<NAME>/`` and ``paper_tables_<budget>_<NAME>_*``. On a fresh clone the published runs are restored
first, so the tables keep them and only missing runs are trained.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks._cli import outputs, paper_task, read_runs, restore_runs, run_file  # noqa: E402
from lagrange.tasks import BODY_SETS, PAPER_TASKS  # noqa: E402
from optim import (APGConfig, AlgorithmConfig, CEAPGConfig, CEMConfig, PAPGConfig, checkpoint, evaluate,  # noqa: E402
                   train)
from optim.base import config_to_dict  # noqa: E402
from optim.checkpoint import write_json, write_text  # noqa: E402
from optim.devices import cpu_core_count, use_cpu_cores  # noqa: E402
from policies import GRUPolicy, MLPPolicy  # noqa: E402

TASKS = ("cartpole", "acrobot", "double_cartpole")  # keys of lagrange.tasks.PAPER_TASKS
ALGOS = ("ce_apg", "papg", "cem", "apg")
# Paper Tables I and II (mean +- std over 8 seeds); "Pendulum" in the paper is the cartpole swing-up.
PAPER = {
    ("ce_apg", "cartpole"): (-355, 10), ("ce_apg", "acrobot"): (3053, 458), ("ce_apg", "double_cartpole"): (4295, 75),
    ("papg", "cartpole"): (-1034, 208), ("papg", "acrobot"): (2456, 647), ("papg", "double_cartpole"): (2335, 431),
    ("cem", "cartpole"): (-3019, 559), ("cem", "acrobot"): (626, 160), ("cem", "double_cartpole"): (-2.7e5, 7.6e5),
    ("apg", "cartpole"): (-3485, 819), ("apg", "acrobot"): (1949, 814), ("apg", "double_cartpole"): (-1982, 4056),
}
PAPER_NOTE = {"apg": "paper: Brax's APG (stochastic MLP), Table I"}
EVAL_EPISODES = 16
WIDTH = {"cartpole": 16, "acrobot": 16, "double_cartpole": 32}  # the paper's GRU width per task


def evaluate_final(task, policy, normalizer, seed):
    """A final policy's ``(returns, balanced flags)`` on the :data:`EVAL_EPISODES` random starts of
    ``PRNGKey(10_000 + seed)``: the evaluation of every training benchmark."""
    run = jax.jit(lambda key: evaluate(task, policy, normalizer, key, EVAL_EPISODES))
    return run(jax.random.PRNGKey(10_000 + seed))


@dataclasses.dataclass(frozen=True)
class Protocol:
    """One (algorithm, task) protocol: the algorithm's ``config``, and the task and policy it trains, named by the
    fields a run's result has always recorded (its ``config`` dict, :meth:`record`): the paper task ``task`` on the
    body set ``bodies`` with episodes of ``horizon`` steps and ``(sin, cos)`` angle observations where
    ``trig_observation``; the ``policy`` "gru" (``policies.GRUPolicy``) or "mlp" of hidden ``width``.
    ``--set`` changes these fields as it changes the config's."""

    task: str
    config: AlgorithmConfig
    bodies: str = "rods"
    horizon: int = 500
    policy: str = "gru"
    width: int = 16
    trig_observation: bool = False

    def __post_init__(self):
        if self.task not in PAPER_TASKS:
            raise ValueError(f"task must be one of {sorted(PAPER_TASKS)}, got {self.task!r}")
        if self.bodies not in BODY_SETS:
            raise ValueError(f"bodies must be one of {list(BODY_SETS)}, got {self.bodies!r}")
        for name in ("horizon", "width"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if self.policy not in ("gru", "mlp"):
            raise ValueError(f"policy must be 'gru' or 'mlp', got {self.policy!r}")
        if not isinstance(self.trig_observation, bool):
            raise ValueError(f"trig_observation must be true or false, got {self.trig_observation!r}")
        if self.trig_observation and not self._trig_is_field():
            if getattr(PAPER_TASKS[self.task], "trig", False) is not True:
                raise ValueError(f"trig_observation: the {self.task} has no (sin, cos) observation layout")

    def _trig_is_field(self) -> bool:
        """Whether the task's observation layout is a field (else a class constant: the double cartpole's is always
        (sin, cos), and ``trig_observation`` changes nothing, as it never did)."""
        return "trig" in {f.name for f in dataclasses.fields(PAPER_TASKS[self.task])}

    def make_task(self):
        """The task: ``PAPER_TASKS[task].<bodies>(...)`` with the horizon and observation of the protocol."""
        options = {"trig": True} if self.trig_observation and self._trig_is_field() else {}
        return paper_task(self.task, self.bodies, horizon=self.horizon, **options)

    def make_policy(self, task):
        """The policy module (its architecture; the algorithm draws its initial weights from the run's key)."""
        return (GRUPolicy if self.policy == "gru" else MLPPolicy).for_task(task, self.width)

    def record(self) -> dict:
        """The protocol as a result's ``config``: the config's fields (``config_to_dict``) with the task and policy
        fields every result has recorded."""
        cfg = config_to_dict(self.config)
        return {"algorithm": cfg.pop("algorithm"), "task": self.task, **cfg, "horizon": self.horizon,
                "policy": self.policy, "width": self.width, "trig_observation": self.trig_observation,
                "bodies": self.bodies}


SETUP_FIELDS = tuple(f.name for f in dataclasses.fields(Protocol) if f.name not in ("task", "config"))
SETUP_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Protocol) if f.name in SETUP_FIELDS}


def config(algo: str, task: str, budget: str) -> Protocol:
    """The protocol of ``algo`` on ``task`` under ``budget``."""
    if budget == "paper":  # plain APG: the interaction count of CE-APG's lineage, 200 x 100 steps of 4 episodes
        configs = {"ce_apg": CEAPGConfig.paper(), "papg": PAPGConfig(), "cem": CEMConfig(),
                   "apg": APGConfig(iterations=200, steps_per_iteration=100, learning_rate=1e-3)}
    elif budget == "smoke":  # a pipeline check only: a few seconds of training per run
        configs = {"ce_apg": CEAPGConfig(num_candidates=4, num_elites=2, iterations=2, apg_steps=2, episodes=1,
                                         fitness_window=1),
                   "papg": PAPGConfig(num_runs=4, iterations=2, apg_steps=2, episodes=1, fitness_window=1),
                   "cem": CEMConfig(num_candidates=4, num_elites=2, iterations=2, episodes=1),
                   "apg": APGConfig(iterations=2, steps_per_iteration=2, episodes=1)}
    else:
        configs = {"ce_apg": CEAPGConfig.laptop(task),
                   "papg": PAPGConfig(num_runs=24, iterations=150, apg_steps=25, episodes=2, lr_start=1e-2,
                                      lr_end=1e-4),
                   "cem": CEMConfig(num_candidates=24, num_elites=6, iterations=2000, episodes=2),
                   "apg": APGConfig(iterations=150, steps_per_iteration=25, episodes=2, learning_rate=3e-3)}
    # the laptop protocol observes the acrobot's angles as (sin, cos): the wrapped angles kept every run at ~350
    return Protocol(task, configs[algo], width=WIDTH[task], trig_observation=budget == "laptop" and task == "acrobot")


def parse_value(text: str):
    """A ``--set`` value: ``300,400`` -> (300, 400); ints, floats, true/false/none; anything else a string."""
    if "," in text:
        return tuple(parse_value(t) for t in text.split(",") if t.strip())
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    if low == "none":
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_overrides(items) -> dict:
    out = {}
    for item in items or ():
        field, sep, value = item.partition("=")
        if not sep or not field.strip():
            raise SystemExit(f"--set must be FIELD=VALUE, got {item!r}")
        out[field.strip()] = parse_value(value)
    return out


def with_overrides(protocol: Protocol, overrides: dict) -> Protocol:
    """``protocol`` with ``overrides`` replaced (and validated): the task and policy fields of :class:`Protocol`
    (``bodies``, ``horizon``, ``policy``, ``width``, ``trig_observation``) and the config's; unknown fields name the
    allowed ones."""
    cfg = protocol.config
    names = [f.name for f in dataclasses.fields(cfg)]
    unknown = sorted(set(overrides) - set(names) - set(SETUP_FIELDS))
    if unknown:
        raise ValueError(f"--set: {type(cfg).__name__} has no field {', '.join(unknown)}; fields: "
                         f"{', '.join(names + list(SETUP_FIELDS))}")
    setup = {k: v for k, v in overrides.items() if k in SETUP_FIELDS}
    cfg = dataclasses.replace(cfg, **{k: v for k, v in overrides.items() if k not in SETUP_FIELDS})
    return dataclasses.replace(protocol, config=cfg, **setup)


def one_run(algo, task, seed, budget, protocol: Protocol, out, progress):
    path = run_file(out, algo, task, seed)
    if path.exists():
        res = json.loads(path.read_text())
        check_same_config(path, res.get("config") or {}, protocol)
        return res
    env = protocol.make_task()
    ckpt = str(path.with_suffix(".eqx"))
    t0 = time.perf_counter()
    try:
        result = train(protocol.config, env, protocol.make_policy(env), jax.random.PRNGKey(seed), checkpoint=ckpt,
                       resume=True, progress=progress, seed=seed)
    except checkpoint.CheckpointError as err:  # e.g. a checkpoint of another protocol, or of an older format
        raise SystemExit(f"cannot resume {ckpt}: {err}. Move it away to retrain the run") from None
    trainer, last = result.trainer, result.history[-1]
    rets, bal = evaluate_final(trainer.task, *trainer.policy(result.state), seed)
    res = {"algo": algo, "task": task, "seed": seed, "budget": budget, "return": float(np.mean(rets)),
           "balanced": bool(np.all(bal)), "balanced_fraction": float(np.mean(bal)), "env_steps": last["env_steps"],
           "best_candidate_fitness": float(last["best_return"]) if "best_return" in last else None,
           "wall_clock_seconds": last["elapsed"], "this_process_seconds": time.perf_counter() - t0,
           "config": protocol.record()}
    write_json(path, res, indent=2)
    return res


def comparable_record(protocol: Protocol, saved: dict) -> dict:
    """``protocol.record()`` to compare with a ``saved`` result's config: a field added since ``saved`` was written
    (to a config class, or ``bodies``) is left out while it has its default, so older runs stay valid. A CEM run
    from before :class:`optim.CEMConfig` existed recorded ``"algorithm": "CEAPGConfig"`` (with ``apg_steps`` 0): the
    same protocol, compared as such."""
    now = protocol.record()
    cfg = protocol.config
    defaults = json.loads(json.dumps({**{f.name: f.default for f in dataclasses.fields(cfg)
                                         if f.default is not dataclasses.MISSING}, **SETUP_DEFAULTS}))
    if isinstance(cfg, CEMConfig) and saved.get("algorithm") == "CEAPGConfig" and saved.get("apg_steps") == 0:
        now["algorithm"] = "CEAPGConfig"
    return {k: v for k, v in now.items() if k in saved or k not in defaults or v != defaults[k]}


def check_same_config(path, saved: dict, protocol: Protocol) -> None:
    """A finished run is reused only if it was trained with ``protocol``: after a preset changes, its old runs would
    otherwise be tabled as the new protocol. Fields added to the config since are compared only when changed."""
    if not saved:  # a result without its config (none of ours): nothing to compare
        return
    detail = checkpoint.config_difference(saved, comparable_record(protocol, saved), saved_as="run", now_as="now")
    if detail:
        raise SystemExit(f"{path} was trained with another config ({detail}). Move it away to retrain it, or give "
                         f"the changed protocol a --variant NAME")


def table(results, budget, variant=""):
    lines = ["| algorithm | task | paper (mean +- std, 8 seeds) | ours: best candidate's fitness (the paper's "
             "statistic) | ours: deterministic evaluation | seeds | seeds balanced | episodes balanced | "
             "env steps / run | wall-clock / run [s] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for algo in ALGOS:
        for task in TASKS:
            rs = [r for r in results if r["algo"] == algo and r["task"] == task]
            if not rs:
                continue
            ret = np.array([r["return"] for r in rs])
            pm, ps = PAPER[(algo, task)]
            fit = np.array([r.get("best_candidate_fitness") for r in rs], dtype=float)
            fit_cell = (f"{fit.mean():.0f} +- {fit.std():.0f}" if np.all(np.isfinite(fit)) else
                        "not recorded" if np.all(np.isnan(fit)) else
                        f"{np.nanmean(fit):.0f} +- {np.nanstd(fit):.0f} ({np.sum(np.isfinite(fit))} seeds)")
            mean = {k: np.mean([r.get(k, np.nan) for r in rs])
                    for k in ("balanced", "balanced_fraction", "env_steps", "wall_clock_seconds")}
            lines.append(f"| {algo} | {task} | {pm:g} +- {ps:g} | {fit_cell} | {ret.mean():.0f} +- {ret.std():.0f} | "
                         f"{len(rs)} | {mean['balanced']:.0%} | {mean['balanced_fraction']:.0%} | "
                         f"{mean['env_steps']:.2e} | {mean['wall_clock_seconds']:.0f} |")
    apg_note = f" {PAPER_NOTE['apg']}." if any(r["algo"] == "apg" for r in results) else ""
    notes = (f"\nBudget: `{budget}`{variant}.{apg_note} Two statistics, mean +- std over seeds: the paper's, the "
             "final iteration's best-candidate fitness in training (CE-APG and PAPG: the mean of its last batch "
             "returns; CEM: its episodes' mean return; APG: the best batch return; 'not recorded' for runs from before "
             f"it was kept), and ours, the return of the final deterministic policy, mean over {EVAL_EPISODES} "
             "evaluation episodes per seed; 'seeds balanced' = fraction of seeds whose every evaluation episode keeps "
             "all links within 0.2 rad of upright over the final 20 %; 'episodes balanced' = the fraction of all "
             f"evaluation episodes that do. Wall-clock on {os.cpu_count()} CPU core(s), {len(jax.devices())} JAX "
             "device(s).")
    return "\n".join([*lines, notes]) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--budget", choices=("paper", "laptop", "smoke"), default="laptop")
    p.add_argument("--tasks", nargs="+", choices=TASKS, default=list(TASKS))
    p.add_argument("--algos", nargs="+", choices=ALGOS, default=list(ALGOS))
    p.add_argument("--seeds", nargs="+", type=int, default=list(range(8)))
    p.add_argument("--out", default="runs/paper_tables")
    p.add_argument("--results", default=None,
                   help="where paper_tables_<budget>_{results.json,tables.md} are written (besides OUT/<budget>/; "
                        "default benchmarks/results, runs/benchmarks for --budget smoke)")
    p.add_argument("--set", action="append", metavar="FIELD=VALUE", dest="overrides",
                   help="change a config field (or bodies, horizon, policy, width, trig_observation) of the selected "
                        "runs (repeatable; 300,400 is a tuple); needs --variant")
    p.add_argument("--variant", default=None, help="name of a --set protocol: its runs and tables are kept apart")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--cpu-devices", type=int, default=cpu_core_count(),
                   help="JAX CPU devices to shard CE-APG/PAPG candidates over (default: one per core)")
    args = p.parse_args(argv)
    args.results = args.results or str(outputs(args.budget == "smoke")[0])
    overrides = parse_overrides(args.overrides)
    if bool(overrides) != bool(args.variant):
        raise SystemExit("--set and --variant go together: a changed protocol is kept apart under its name")
    if args.variant and not args.variant.replace("_", "").replace("-", "").isalnum():
        raise SystemExit(f"--variant must be letters, digits, '_' or '-', got {args.variant!r}")
    use_cpu_cores(args.cpu_devices)
    # every selected config, built (and --set validated) before any training
    try:
        configs = {(algo, task): with_overrides(config(algo, task, args.budget), overrides)
                   for algo in args.algos for task in args.tasks}
    except ValueError as err:  # an unknown field or a value the config rejects: a usage error, not a traceback
        p.error(str(err))
    name = args.budget + (f"_{args.variant}" if args.variant else "")
    out = os.path.join(args.out, name)
    restore_runs(out, pathlib.Path(args.results, f"paper_tables_{name}_results.json"))
    for algo in args.algos:
        for task in args.tasks:
            for seed in args.seeds:
                r = one_run(algo, task, seed, args.budget, configs[algo, task], out, not args.no_progress)
                print(f"{algo:7s} {task:16s} seed {seed}: return {r['return']:8.0f} balanced {r['balanced']} "
                      f"{r['env_steps']:.2e} steps {r['wall_clock_seconds']:.0f} s", flush=True)
    # The tables cover every finished run of this budget, selected now or in an earlier invocation.
    results = sorted(read_runs(out), key=lambda r: (ALGOS.index(r["algo"]), TASKS.index(r["task"]), r["seed"]))
    variant = (f", variant `{args.variant}`: " + ", ".join(f"`{k}={v!r}`" for k, v in overrides.items())
               if args.variant else "")
    md = table(results, args.budget, variant)
    for folder in (out, args.results):
        stem = "" if folder == out else f"paper_tables_{name}_"
        write_json(os.path.join(folder, f"{stem}results.json"), results, indent=2)
        write_text(os.path.join(folder, f"{stem}tables.md"), md)
    print(md)


if __name__ == "__main__":
    main()
