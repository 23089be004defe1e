"""Checkpoints (optim/checkpoint.py): a round trip gives the state back bit for bit with its header; a mismatched
config, a cut file, a foreign file and an unknown version are refused with a message naming the cause; no temporary
file is left behind and the file gets an ordinary mode."""

import json
import os

import jax
import pytest

from optim import apg, ce_apg, checkpoint
from optim._loop import params_equal
from tests.helpers import tiny_ce_apg_config


TINY = tiny_ce_apg_config()


@pytest.fixture(scope="module")
def tiny_trainer():
    return ce_apg.make_trainer(TINY)


def test_checkpoint_round_trip_and_errors(tiny_trainer, tmp_path):
    cfg = apg.config_to_dict(TINY)
    state, _ = tiny_trainer.update(tiny_trainer.init(jax.random.PRNGKey(1)))
    path = tmp_path / "ckpt.eqx"
    checkpoint.save(path, state, config=cfg, seed=1, history=[{"best_return": 1.0}])
    loaded, head = checkpoint.load(path, tiny_trainer.init(jax.random.PRNGKey(0)), config=cfg)
    assert params_equal(loaded, state)
    assert head["seed"] == 1 and head["version"] == checkpoint.VERSION and head["config"] == cfg
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".ckpt-")]  # no temp file left behind
    old = os.umask(0o022)
    try:  # an ordinary file's mode under the umask (mkstemp alone would leave 0600)
        checkpoint.save(tmp_path / "mode.eqx", state, config=cfg)
    finally:
        os.umask(old)
    assert (tmp_path / "mode.eqx").stat().st_mode & 0o777 == 0o644

    other = dict(cfg, num_elites=3)
    with pytest.raises(checkpoint.CheckpointError, match="num_elites"):
        checkpoint.load(path, state, config=other)
    data = path.read_bytes()
    (tmp_path / "cut.eqx").write_bytes(data[: len(data) - 40])
    with pytest.raises(checkpoint.CheckpointError, match="corrupt"):
        checkpoint.load(tmp_path / "cut.eqx", state)
    (tmp_path / "junk.eqx").write_bytes(b"\x00\xffnot a checkpoint")
    with pytest.raises(checkpoint.CheckpointError, match="not a lagrange checkpoint"):
        checkpoint.load(tmp_path / "junk.eqx", state)
    head_v2 = json.dumps({"format": checkpoint.FORMAT, "version": 99, "config": cfg}).encode()
    (tmp_path / "v2.eqx").write_bytes(head_v2 + b"\n" + data.split(b"\n", 1)[1])
    with pytest.raises(checkpoint.CheckpointError, match="version 99"):
        checkpoint.load(tmp_path / "v2.eqx", state)
