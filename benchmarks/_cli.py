"""Command-line helpers shared by the benchmark scripts: argument checks and finding paper-tables checkpoints."""

from __future__ import annotations

import os

from lagrange.tasks import BODIES


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


def add_checkpoint_flags(parser, *, runs: str, seeds: list[int]) -> None:
    """``--runs``, ``--task``, ``--seeds`` and ``--cpu-devices`` of a script that reads paper-tables checkpoints."""
    parser.add_argument("--runs", default=runs, help="folder of paper_tables checkpoints ce_apg_<task>_<seed>.eqx")
    parser.add_argument("--task", choices=("acrobot", "cartpole", "double_cartpole"), default="acrobot")
    parser.add_argument("--seeds", nargs="+", type=int, default=seeds)
    parser.add_argument("--cpu-devices", type=int, default=1)


def add_bodies_flag(parser) -> None:
    """``--bodies rods|brax_v1``: the paper task's bodies (``lagrange.tasks.make_task``)."""
    parser.add_argument("--bodies", choices=BODIES, default="rods", help="the task's bodies (lagrange.tasks.make_task)")


def bodies_suffix(bodies: str) -> str:
    """``""`` for the rods, else ``"_<bodies>"``: a result on other bodies gets its own file beside the rods' one."""
    return "" if bodies == "rods" else f"_{bodies}"


def bodies_marker(bodies: str) -> dict:
    """``{}`` for the rods, else ``{"bodies": bodies}``: marks a result dict on other bodies, so the rods' result
    files stay as they were."""
    return {} if bodies == "rods" else {"bodies": bodies}


def marked_bodies(result: dict) -> str:
    """The bodies a result dict (or a config dict) names: its ``"bodies"``, the rods where there is none (the inverse
    of :func:`bodies_marker`; results and configs from before the field existed are on the rods)."""
    return result.get("bodies", "rods")


def runs_result_path(out: str | None, results, stem: str, runs: str) -> str:
    """``out``, or ``results/<stem>_<name of the runs folder>.json``."""
    return out or os.path.join(results, f"{stem}_{os.path.basename(os.path.normpath(runs))}.json")
