"""optim.cli, the examples' driver, in process: its flags and their defaults; bad flags, an --out that cannot be
written and a checkpoint of another run refused in one line before any training; a tiny run (1 iteration on 5-step
episodes) that writes every artefact, whose results are the evaluation of the policy its checkpoint holds; a folder
that holds a run never overwritten without --overwrite, nor resumed on another schedule without an explicit
--iterations; strict JSON results (a NaN written as null, and said so); and the learning curve drawn from a CE-APG
history and from a SHAC history with deterministic evaluations."""

import dataclasses
import json

import jax
import numpy as np
import pytest

import optim
import lagrange as lg
from lagrange.tasks import ChainSwingup
from optim.base import config_to_dict
from optim.cli import EVAL_EPISODES, learning_curve, prepare_run, swingup_main, swingup_parser, write_results
from policies import GRUPolicy

CFG = optim.CEAPGConfig(num_candidates=4, num_elites=2, iterations=1, apg_steps=1, episodes=1, fitness_window=1)
QUICK = optim.CEAPGConfig(num_candidates=2, num_elites=1, iterations=1, apg_steps=1, episodes=1, fitness_window=1)
# two body sets of a 5-step pendulum swing-up: a rod, and a rod with the Brax v1 bodies' inertia of 1 kg m^2 (the
# smallest task, the least to compile)
TASKS = {"rods": lambda: ChainSwingup(lg.systems.pendulum(gear=5.0), dt=0.05, horizon=5, bodies="rods"),
         "brax_v1": lambda: ChainSwingup(lg.systems.pendulum(gear=5.0, inertia=1.0), dt=0.05, horizon=5,
                                         bodies="brax_v1")}


def policy(task):
    return GRUPolicy.for_task(task, width=4)


def main(out, *flags):
    return swingup_main("d", str(out), CFG, QUICK, tasks=TASKS, policy=policy, paper_return=123.0,
                        argv=["--no-progress", "--cpu-devices", "1", *flags])


def test_parser_defaults_and_bodies():
    args = swingup_parser("d", "runs/x", bodies=("rods", "brax_v1")).parse_args([])
    assert (args.seed, args.iterations, args.out, args.resume, args.overwrite, args.quick, args.no_progress,
            args.bodies) == (0, None, "runs/x", False, False, False, False, "rods")
    assert args.cpu_devices >= 1
    assert swingup_parser("d", "runs/x", bodies=("rods", "brax_v1")).parse_args(["--bodies", "brax_v1"]).bodies == \
        "brax_v1"
    for own in (swingup_parser("d", "runs/x", bodies=("custom",)), swingup_parser("d", "runs/x")):
        assert not hasattr(own.parse_args([]), "bodies")
        with pytest.raises(SystemExit):
            own.parse_args(["--bodies", "rods"])  # a chain of one's own: no --bodies


@pytest.mark.parametrize("flags, message", [(["--iterations", "0"], "--iterations must be >= 1, got 0"),
                                            (["--cpu-devices", "0"], "--cpu-devices must be >= 1, got 0"),
                                            (["--resume", "--overwrite"], "--resume continues .* give one"),
                                            (["--out", ""], "--out is empty; give the folder")])
def test_bad_flags_exit_with_one_line(tmp_path, flags, message):
    with pytest.raises(SystemExit, match=message):
        main(tmp_path / "run", *flags)
    assert not (tmp_path / "run").exists()  # refused before anything was written
    (tmp_path / "file").write_text("x")
    for out, message in ((tmp_path / "file", r"--out '.*file' is a file; give a folder"),
                         (tmp_path / "file" / "run", r"--out '.*checkpoint.eqx' cannot be written: its folder .* is")):
        with pytest.raises(SystemExit, match=message):
            main(out, "--out", str(out))
    with pytest.raises(ValueError, match="tasks must name at least one body set"):
        swingup_main("d", str(tmp_path), CFG, CFG, tasks={}, policy=policy, argv=[])


def test_tiny_run_writes_every_artefact(tmp_path):
    out = tmp_path / "run"
    res = main(out, "--out", str(out), "--bodies", "brax_v1", "--seed", "3")
    for name in ("checkpoint.eqx", "results.json", "learning_curve.png", "swingup.png", "swingup.gif"):
        assert (out / name).stat().st_size > 0, name
    assert json.loads((out / "results.json").read_text()) == res
    assert (res["task"], res["bodies"], res["seed"], res["iterations"], res["paper_return"]) == \
        ("chain", "brax_v1", 3, 1, 123.0)
    assert res["config"] == config_to_dict(CFG) and res["devices"] == len(jax.devices())
    assert res["env_steps"] == 4 * 1 * 1 * 5 and res["horizon"] == 5 and res["eval_episodes"] == EVAL_EPISODES
    # the shipped policy is chosen on selection episodes; its reported return is its evaluation on other starts
    assert set(res["selection_returns"]) == set(res["returns_by_policy"]) == {"best", "mean"}
    assert res["policy"] == max(res["selection_returns"], key=res["selection_returns"].get)
    task = TASKS["brax_v1"]()
    trainer, state, head = optim.load(out / "checkpoint.eqx", task, policy(task))
    assert head["seed"] == 3 and head["identity"]["bodies"] == "brax_v1" and int(state.iteration) == 1
    rets, bal = optim.evaluate(task, *trainer.policy(state, res["policy"]), jax.random.PRNGKey(10_003), EVAL_EPISODES)
    np.testing.assert_allclose(res["return"], float(np.mean(rets)), rtol=1e-12)
    assert res["return"] == res["returns_by_policy"][res["policy"]]
    assert res["balanced_fraction"] == float(np.mean(bal))
    # --resume reads the checkpoint: another body set or the --quick config cannot continue it
    with pytest.raises(SystemExit, match=r"cannot resume: .*bodies: checkpoint 'brax_v1', requested 'rods'"):
        main(out, "--out", str(out), "--seed", "3", "--resume", "--iterations", "2")
    with pytest.raises(SystemExit, match=r"cannot resume: .*num_candidates: checkpoint 4, requested 2"):
        main(out, "--out", str(out), "--bodies", "brax_v1", "--seed", "3", "--resume", "--quick", "--iterations", "2")
    # the folder holds a run: a new one without --resume or --overwrite is refused, the checkpoint left as it was
    before = (out / "checkpoint.eqx").read_bytes()
    with pytest.raises(SystemExit, match=r"holds a run \(checkpoint.eqx, results.json\); --resume continues it, "
                                         r"--overwrite replaces it"):
        main(out, "--out", str(out), "--bodies", "brax_v1", "--seed", "3")
    assert (out / "checkpoint.eqx").read_bytes() == before
    assert prepare_run(str(out), CFG, resume=False, overwrite=True) == str(out / "checkpoint.eqx")  # and kept
    assert (out / "checkpoint.eqx").read_bytes() == before
    # a resume on another length (a --quick run continued without --quick) would mix two learning-rate schedules
    longer = dataclasses.replace(CFG, iterations=3)
    with pytest.raises(SystemExit, match=r"is a run of 1 iterations and these flags ask for 3, whose learning-rate "
                                         r"schedule differs: resume it with --quick if it was a quick run; .* pass "
                                         r"--iterations 3 explicitly; or start afresh with --overwrite"):
        swingup_main("d", str(out), longer, QUICK, tasks=TASKS, policy=policy, argv=["--resume", "--bodies", "brax_v1"])
    with pytest.raises(SystemExit, match=r"resume it without --quick if it was a full run"):
        prepare_run(str(out), longer, resume=True, quick=True)


def test_results_are_strict_json(tmp_path, capsys):
    """A return that is NaN (a policy whose evaluation blew up) is written as null, and a warning names it."""
    path = tmp_path / "results.json"
    written = write_results(str(path), {"return": float("nan"), "by": {"best": float("-inf"), "mean": 1.5},
                                        "curve": [{"return": float("inf")}], "seed": 0})
    assert written == {"return": None, "by": {"best": None, "mean": 1.5}, "curve": [{"return": None}], "seed": 0}
    assert json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"not strict JSON: {c}")) == written
    err = capsys.readouterr().err
    assert "by.best, curve[0].return, return not finite (NaN or infinite): written as null" in err


def _drawn(monkeypatch, tmp_path, history, curve, **kw):
    """The learning curve's lines by label, and its axes (the figure is caught as it is saved)."""
    from matplotlib.figure import Figure

    figures, save = [], Figure.savefig

    def savefig(fig, *args, **kwargs):
        figures.append(fig)
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    path = tmp_path / "curve.png"
    learning_curve(history, curve, str(path), title="t", **kw)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (fig,) = figures
    ax = fig.axes[0]
    lines = {line.get_label(): (np.asarray(line.get_xdata()), np.asarray(line.get_ydata())) for line in ax.get_lines()}
    return lines, ax


def test_learning_curve_of_a_ce_apg_history(monkeypatch, tmp_path):
    """The best candidate, the elite mean and all candidates against env steps, the paper's return; the axes scale to
    the best and elite curves, not to a mean dragged down by candidates that blew up (-1e5) or a -inf best."""
    history = [{"env_steps": 100.0 * i, "best_return": b, "elite_return": e, "mean_return": m, "nonfinite": 0.0}
               for i, (b, e, m) in enumerate([(-np.inf, 5.0, -1e5), (20.0, 10.0, 0.0), (40.0, 30.0, 15.0)], 1)]
    lines, ax = _drawn(monkeypatch, tmp_path, history, [], paper_return=50.0)
    assert set(lines) == {"best candidate", "elite mean", "all candidates (finite)", "paper CE-APG (50)"}
    np.testing.assert_array_equal(lines["best candidate"][0], [100.0, 200.0, 300.0])
    np.testing.assert_array_equal(lines["elite mean"][1], [5.0, 10.0, 30.0])
    np.testing.assert_array_equal(lines["all candidates (finite)"][1], [-1e5, 0.0, 15.0])
    lo, hi = ax.get_ylim()
    assert lo == pytest.approx(5.0 - 0.05 * 45.0) and hi == pytest.approx(50.0 + 0.05 * 45.0)
    assert ax.get_title() == "t" and ax.get_xlabel() == "simulated environment steps"


def test_learning_curve_of_a_shac_history(monkeypatch, tmp_path):
    """SHAC's stochastic training episodes (NaN in a window where none finished) and the deterministic evaluations,
    each against its env steps."""
    history = [{"env_steps": 16.0 * i, "episode_return": r, "value_loss": 1e6, "nonfinite": 0.0}
               for i, r in enumerate([np.nan, 10.0, 20.0], 1)]
    curve = [{"iteration": 0, "env_steps": 0.0, "return": 5.0}, {"iteration": 3, "env_steps": 48.0, "return": 25.0}]
    lines, ax = _drawn(monkeypatch, tmp_path, history, curve)
    assert set(lines) == {"training episodes (stochastic)", "deterministic evaluation"}
    np.testing.assert_array_equal(lines["training episodes (stochastic)"][0], [16.0, 32.0, 48.0])
    np.testing.assert_array_equal(lines["deterministic evaluation"][0], [0.0, 48.0])
    np.testing.assert_array_equal(lines["deterministic evaluation"][1], [5.0, 25.0])
    assert ax.get_ylim() == pytest.approx((5.0 - 1.0, 25.0 + 1.0))  # 5% of the 20 spanned; the loss is not drawn
