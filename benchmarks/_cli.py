"""Shared helpers of the benchmark scripts: where they write, the ``--bodies`` flag, the paper tasks by name, the
per-run result files of the training benchmarks, a markdown table of result rows, figures, and the MJCF files that
other packages ship."""

from __future__ import annotations

import importlib.util
import json
import pathlib

from lagrange.tasks import BODY_SETS, PAPER_TASKS
from optim.checkpoint import write_json

REPO = pathlib.Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"  # the published tables (JSON, markdown)
IMG = REPO / "docs" / "img"  # the published plots
QUICK = REPO / "runs" / "benchmarks"  # --quick runs: git-ignored, never published


def outputs(quick: bool) -> tuple[pathlib.Path, pathlib.Path]:
    """``(folder of result files, folder of plots)``: :data:`RESULTS` and :data:`IMG`, or :data:`QUICK` twice."""
    return (QUICK, QUICK) if quick else (RESULTS, IMG)


def asset(package: str, *parts: str) -> pathlib.Path:
    """A file shipped inside an installed ``package`` (not imported), e.g. ``asset("brax", "envs", "assets",
    "hopper.xml")``; :func:`gymnasium_model` for Gymnasium's MuJoCo models."""
    return pathlib.Path(importlib.util.find_spec(package).submodule_search_locations[0]).joinpath(*parts)


def gymnasium_model(name: str) -> pathlib.Path:
    """Gymnasium's MJCF model ``name`` (``"hopper"``, ``"half_cheetah"``, ...)."""
    return asset("gymnasium", "envs", "mujoco", "assets", f"{name}.xml")


def paper_task(name: str, bodies: str = "rods", **options):
    """The paper task called ``name`` (a key of ``lagrange.tasks.PAPER_TASKS``) on the body set ``bodies`` (one of
    ``lagrange.tasks.BODY_SETS``: the task class's constructor of that name, e.g. ``Acrobot.brax_v1``); ``options``
    are task fields (``trig``, ``horizon``, ...) passed to that constructor."""
    if name not in PAPER_TASKS:
        raise ValueError(f"task must be one of {sorted(PAPER_TASKS)}, got {name!r}")
    if bodies not in BODY_SETS:
        raise ValueError(f"bodies must be one of {list(BODY_SETS)}, got {bodies!r}")
    return getattr(PAPER_TASKS[name], bodies)(**options)


def add_bodies_flag(parser) -> None:
    """``--bodies rods|brax_v1``: the paper task's body set (:func:`paper_task`)."""
    parser.add_argument("--bodies", choices=BODY_SETS, default="rods",
                        help="the task's body set (the task class's constructor of that name, e.g. Acrobot.brax_v1)")


def bodies_suffix(bodies: str) -> str:
    """``""`` for the rods, else ``"_<bodies>"``: a result on other bodies gets its own file beside the rods' one."""
    return "" if bodies == "rods" else f"_{bodies}"


def bodies_marker(bodies: str) -> dict:
    """``{}`` for the rods, else ``{"bodies": bodies}``: marks a result dict on other bodies."""
    return {} if bodies == "rods" else {"bodies": bodies}


def marked_bodies(result: dict) -> str:
    """The bodies a result (or config) dict names, the rods where it names none (:func:`bodies_marker`'s inverse)."""
    return result.get("bodies", "rods")


def run_file(folder, algo: str, task: str, seed: int) -> pathlib.Path:
    """Where a training benchmark keeps one run's result: ``folder/<algo>_<task>_<seed>.json``."""
    return pathlib.Path(folder, f"{algo}_{task}_{seed}.json")


def read_runs(folder) -> list[dict]:
    """Every run file (:func:`run_file`) in ``folder``, none where it does not exist, in no particular order."""
    files = pathlib.Path(folder).glob("*_*.json")
    return [json.loads(p.read_text()) for p in files if p.stem.rpartition("_")[2].isdigit()]


def restore_runs(folder, published: pathlib.Path, runs_of=lambda saved: saved, keep=None) -> None:
    """On a fresh clone (``runs/`` is not in git: no run file in ``folder``), the runs of the ``published`` JSON
    (``runs_of(its content)``, a list of run dicts) written back to their run files, so that the tables keep them and
    they are not trained again. With ``keep`` (a test of a run dict), whatever the folder holds: each published run
    that ``keep`` accepts and whose run file is missing."""
    pathlib.Path(folder).mkdir(parents=True, exist_ok=True)
    if (keep is None and read_runs(folder)) or not published.exists():
        return
    runs = [r for r in runs_of(json.loads(published.read_text())) if keep is None
            or (keep(r) and not run_file(folder, r["algo"], r["task"], r["seed"]).exists())]
    for r in runs:
        write_json(run_file(folder, r["algo"], r["task"], r["seed"]), r, indent=2)
    if runs:
        print(f"restored {len(runs)} run files into {folder} from {published}")


def markdown_table(rows, keys) -> str:
    """``rows`` (dicts) as a markdown table of the columns ``keys``: floats to 3 significant digits, a missing entry
    ``None``."""
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        lines.append("| " + " | ".join(f"{r.get(k):.3g}" if isinstance(r.get(k), float) else str(r.get(k))
                                      for k in keys) + " |")
    return "\n".join(lines)


def subplots(*args, **kwargs):
    """``matplotlib.pyplot.subplots(*args, **kwargs)`` on the Agg backend (files, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kwargs)


def save_figure(fig, path: pathlib.Path, dpi: int, **layout) -> None:
    """``fig`` laid out (``tight_layout(**layout)``), written to ``path`` (its folder made) and closed."""
    import matplotlib.pyplot as plt

    fig.tight_layout(**layout)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
