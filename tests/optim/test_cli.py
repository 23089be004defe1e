"""optim.cli, the examples' driver, in process: its flags and their defaults, and bad flags refused in one line
before any training (the runs themselves and their artefacts are tested through the examples, test_examples)."""

import pytest

from optim.ce_apg import CEAPGConfig
from optim.cli import swingup_main, swingup_parser

CFG = CEAPGConfig(task="acrobot", num_candidates=4, num_elites=2, iterations=1, apg_steps=1, episodes=1, horizon=5,
                  fitness_window=1)


def test_parser_defaults_and_bodies():
    args = swingup_parser("d", "runs/x").parse_args([])
    assert (args.seed, args.iterations, args.out, args.resume, args.quick, args.no_progress, args.bodies) == \
        (0, None, "runs/x", False, False, False, "rods")
    assert args.cpu_devices >= 1
    assert swingup_parser("d", "runs/x").parse_args(["--bodies", "brax_v1"]).bodies == "brax_v1"
    own = swingup_parser("d", "runs/x", bodies=False)
    assert not hasattr(own.parse_args([]), "bodies")
    with pytest.raises(SystemExit):
        own.parse_args(["--bodies", "rods"])  # a chain of one's own: no --bodies


@pytest.mark.parametrize("flags, message", [(["--iterations", "0"], "--iterations must be >= 1, got 0"),
                                            (["--cpu-devices", "0"], "--cpu-devices must be >= 1, got 0")])
def test_bad_flags_exit_with_one_line(tmp_path, flags, message):
    with pytest.raises(SystemExit, match=message):
        swingup_main("d", str(tmp_path / "run"), CFG, CFG, argv=flags)
    assert not (tmp_path / "run").exists()  # refused before anything was written
