"""Command-line helpers of the research scripts: argument checks, paper-tables checkpoints, result paths."""

from __future__ import annotations

import dataclasses
import os

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def at_least(**minimums) -> None:
    """``at_least(steps=(args.steps, 1), ...)``: exit naming the flag (``--steps``) if a value is below its minimum."""
    for name, (value, lo) in minimums.items():
        if value < lo:
            raise SystemExit(f"--{name.replace('_', '-')} must be >= {lo}, got {value}")


def paper_tables_checkpoint(runs: str, task: str, seed: int) -> str:
    """``runs/ce_apg_<task>_<seed>.eqx`` as written by ``benchmarks/paper_tables.py``; exits naming the command that
    makes it if it is missing."""
    path = os.path.join(runs, f"ce_apg_{task}_{seed}.eqx")
    if not os.path.exists(path):
        raise SystemExit(f"{path} does not exist: run benchmarks/paper_tables.py for seed {seed} first (--runs names "
                         f"the folder it writes, e.g. runs/paper_tables/laptop_ep1 for --variant ep1)")
    return path


def load_run(path: str, task=None, policy=None):
    """``(trainer, state)`` of a checkpoint that :func:`optim.train` wrote (``benchmarks/paper_tables.py``'s runs, the
    examples' ``checkpoint.eqx``), by :func:`optim.load`. Where ``task`` or ``policy`` is not given it is rebuilt from
    the header's record of them: the paper task of that class on its body set with its horizon, observing
    ``(sin, cos)`` where its observation size says so; a ``policies`` class of that name, of the width that gives the
    recorded parameter count. Checkpoints of the format before issue 30 (version 1) are refused
    (:class:`optim.checkpoint.CheckpointError`): re-create them with the current scripts."""
    import optim
    import policies
    from benchmarks._cli import paper_task
    from lagrange.tasks import PAPER_TASKS
    from optim import checkpoint

    identity = checkpoint.read_header(path).get("identity") or {}
    if task is None:
        names = {cls.__name__: name for name, cls in PAPER_TASKS.items()}
        if identity.get("task") not in names:
            raise SystemExit(f"{path} was written for a {identity.get('task')!r} task, not a paper task: pass the task")
        name = names[identity["task"]]
        task = paper_task(name, identity.get("bodies") or "rods", horizon=identity["horizon"])
        if "trig" in {f.name for f in dataclasses.fields(task)} and \
                task.observation_size != identity["observation_size"]:
            task = dataclasses.replace(task, trig=True)
    if policy is None:
        cls = getattr(policies, str(identity.get("policy")), None)
        if not hasattr(cls, "for_task"):
            raise SystemExit(f"{path} was written for a {identity.get('policy')!r} policy: pass the policy")
        for width in range(1, 1025):  # the parameter count grows with the width
            policy = cls.for_task(task, width)
            if optim.flatten_policy(policy)[0].size >= identity["policy_parameters"]:
                break
    trainer, state, _ = optim.load(path, task, policy)
    return trainer, state


def add_checkpoint_flags(parser, *, runs: str, seeds: list[int]) -> None:
    """``--runs``, ``--task``, ``--seeds`` and ``--cpu-devices`` of a script that reads paper-tables checkpoints."""
    parser.add_argument("--runs", default=runs, help="folder of paper_tables checkpoints ce_apg_<task>_<seed>.eqx")
    parser.add_argument("--task", choices=("acrobot", "cartpole", "double_cartpole"), default="acrobot")
    parser.add_argument("--seeds", nargs="+", type=int, default=seeds)
    parser.add_argument("--cpu-devices", type=int, default=1)


def runs_result_path(out: str | None, results, stem: str, runs: str) -> str:
    """``out``, or ``results/<stem>_<name of the runs folder>.json``."""
    return out or os.path.join(results, f"{stem}_{os.path.basename(os.path.normpath(runs))}.json")


def repo_relative(path) -> str:
    """``path`` relative to the repository root when it lies inside it (so result files do not record this
    machine's folders), else as given."""
    path = os.fspath(path)
    full = os.path.abspath(path)
    return os.path.relpath(full, REPO) if os.path.commonpath([full, REPO]) == REPO else path
