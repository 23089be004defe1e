"""The host loop (optim/_loop.py, ``optim.run``): a run killed and resumed from its checkpoint equals an
uninterrupted one, a resume with another seed or fewer iterations is refused, and a checkpoint written before a config
field existed resumes at that field's default, and only then."""

import dataclasses

import jax
import pytest

from optim import ce_apg, checkpoint
from optim._loop import params_equal, run
from tests.helpers import tiny_ce_apg_config


TINY = tiny_ce_apg_config()


@pytest.fixture(scope="module")
def tiny_trainer():
    return ce_apg.make_trainer(TINY)


def test_resume_equals_uninterrupted(tiny_trainer, tmp_path):
    key = jax.random.PRNGKey(3)
    full, hist_full = run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "a.eqx"), progress=False, seed=3)
    # "killed" after 1 iteration, then resumed from its checkpoint
    run(tiny_trainer, key, iterations=1, ckpt_path=str(tmp_path / "b.eqx"), progress=False, seed=3)
    resumed, hist = run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "b.eqx"), resume=True,
                        progress=False, seed=3)
    assert int(resumed.iteration) == 3 and len(hist) == 3
    assert params_equal(resumed, full)
    assert [h["best_return"] for h in hist] == [h["best_return"] for h in hist_full]
    assert not params_equal(resumed.mean, tiny_trainer.init(key).mean)  # it did train
    with pytest.raises(checkpoint.CheckpointError, match="seed"):
        run(tiny_trainer, key, iterations=3, ckpt_path=str(tmp_path / "b.eqx"), resume=True, progress=False, seed=4)
    # a shorter run (e.g. --quick) cannot resume a longer one: it would report the longer run as its own
    with pytest.raises(checkpoint.CheckpointError, match="iterations=2"):
        run(tiny_trainer, key, iterations=2, ckpt_path=str(tmp_path / "b.eqx"), resume=True, progress=False, seed=3)


def test_resume_a_checkpoint_written_before_a_config_field_existed(tiny_trainer, tmp_path):
    """A config field added later (``upright_starts``) matches an older checkpoint at its default, and only then."""
    key = jax.random.PRNGKey(3)
    path = str(tmp_path / "old.eqx")
    state, hist = run(tiny_trainer, key, iterations=1, ckpt_path=path, progress=False, seed=3)
    head = checkpoint.read_header(path)
    old = {k: v for k, v in head["config"].items() if k != "upright_starts"}
    checkpoint.save(path, state, config=old, seed=3, iteration=1, history=hist)
    resumed, hist2 = run(tiny_trainer, key, iterations=2, ckpt_path=path, resume=True, progress=False, seed=3)
    assert int(resumed.iteration) == 2 and len(hist2) == 2
    checkpoint.save(path, state, config=old, seed=3, iteration=1, history=hist)
    other = ce_apg.make_trainer(dataclasses.replace(TINY, upright_starts=0.5))
    with pytest.raises(checkpoint.CheckpointError, match="upright_starts"):
        run(other, key, iterations=2, ckpt_path=path, resume=True, progress=False, seed=3)
