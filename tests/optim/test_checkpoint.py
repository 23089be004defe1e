"""Checkpoints (optim/checkpoint.py, and their use by ``optim.train`` and ``optim.load``): a round trip gives the state
back bit for bit with its header and a SHA-256 digest of both, atomically (no temporary file left, an ordinary file
mode); a resume or a load refuses, with a message naming the cause, another config (the field), another algorithm,
another task or policy (the header's identity, down to the chain's masses and gears, ``dt``, noise, solver and
substeps), another seed, a cut, extended or flipped byte (the digest), an iteration counter that disagrees with itself
or is negative, a NaN state, a foreign file, a version-1 file and an unknown version; a config field added since a
checkpoint was written matches it at its default, and only then; a checkpoint written before the digest and the task's
fields were recorded still resumes; a checkpoint path that cannot be written is refused before any work."""

import dataclasses
import hashlib
import json
import os

import jax
import jax.numpy as jnp
import pytest

import lagrange as lg
import optim
from lagrange.tasks import ChainSwingup
from optim import checkpoint
from optim.base import config_to_dict
from tests.helpers import (RUN_KEY, RUN_SEED, pendulum_swingup, small_problem, states_equal, tiny_acrobot, tiny_gru,
                           tiny_mlp)


def test_save_and_load_round_trip(tmp_path):
    task = tiny_acrobot()
    trainer = optim.APGConfig().make_trainer(task, tiny_gru(task))
    state = trainer.init(jax.random.PRNGKey(1))  # random weights, Adam's state, a normaliser
    cfg = config_to_dict(trainer.config)
    path = tmp_path / "ckpt.eqx"
    checkpoint.save(path, state, config=cfg, seed=1, history=[{"best_return": 1.0}])
    loaded, head = checkpoint.load(path, trainer.init(jax.random.PRNGKey(0)), config=cfg)
    assert states_equal(loaded, state) and not states_equal(loaded, trainer.init(jax.random.PRNGKey(0)))
    assert checkpoint.VERSION == 2 and head == {"format": checkpoint.FORMAT, "version": 2, "config": cfg, "seed": 1,
                                                "history": [{"best_return": 1.0}]}
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".ckpt-")]  # no temporary file left behind
    line, payload = path.read_bytes().split(b"\n", 1)  # the digest: SHA-256 of the header without it, and the state
    written = json.loads(line)
    digest = written.pop("digest")
    assert digest == hashlib.sha256(json.dumps(written).encode() + b"\n" + payload).hexdigest()
    old = os.umask(0o022)
    try:  # an ordinary file's mode under the umask (mkstemp alone would leave 0600)
        checkpoint.save(tmp_path / "mode.eqx", state, config=cfg)
    finally:
        os.umask(old)
    assert (tmp_path / "mode.eqx").stat().st_mode & 0o777 == 0o644
    with pytest.raises(checkpoint.CheckpointError, match=r"different config \(episodes: checkpoint 4, requested 3\)"):
        checkpoint.load(path, state, config=dict(cfg, episodes=3))
    checkpoint.write_json(tmp_path / "sub" / "results.json", {"return": 1.5})  # creates the folder, atomically
    assert json.loads((tmp_path / "sub" / "results.json").read_text()) == {"return": 1.5}
    with pytest.raises(IsADirectoryError, match=r"is a folder; give a file path to write"):
        checkpoint.save(tmp_path / "sub", state, config=cfg)


CFG, TASK, POLICY, _ = small_problem("CEAPGConfig")  # the short_run fixture's CE-APG run: 2 iterations


@pytest.fixture(scope="module")
def run(short_run):
    """The checkpoint of a 2-iteration CE-APG run (seed 7), its task, policy and final state."""
    result, path, task, policy, _ = short_run("CEAPGConfig")
    return path, task, policy, result.state


def _resume(path, config=CFG, task=TASK, policy=POLICY, seed=RUN_SEED):
    return optim.train(config, task, policy, RUN_KEY, checkpoint=path, resume=True, seed=seed, progress=False)


def test_resume_and_load_accept_their_own_run(run):
    path, task, policy, state = run
    assert states_equal(_resume(path).state, state)  # nothing left to do: the checkpoint's state
    trainer, loaded, head = optim.load(path, task, policy)
    assert trainer.config == CFG and states_equal(loaded, state) and head["seed"] == RUN_SEED


@pytest.mark.parametrize("change, message", [
    (dict(config=dataclasses.replace(CFG, num_elites=3)), r"num_elites: checkpoint 2, requested 3"),
    (dict(config=dataclasses.replace(CFG, normalize=False)), r"normalize: checkpoint True, requested False"),
    (dict(config=optim.APGConfig(iterations=2)), r"algorithm: checkpoint 'CEAPGConfig', requested 'APGConfig'"),
    (dict(task=pendulum_swingup(horizon=30, noise=0.5)),
     r"another task or policy \(horizon: checkpoint 20, requested 30; task\.horizon: checkpoint 20, requested 30\)"),
    (dict(task=pendulum_swingup(horizon=20, noise=0.5, bodies="brax_v1")),
     r"another task or policy \(bodies: checkpoint None, requested 'brax_v1'; task\.bodies: checkpoint None"),
    (dict(task=ChainSwingup(lg.systems.pendulum(gear=5.0, mass=2.0), dt=0.05, horizon=20, noise=0.5)),
     r"another task or policy \(task\.chain\.bodies\[0\]\.inertia: .*; task\.chain\.bodies\[0\]\.mass: "
     r"checkpoint 'float64\[\] \[1\.0\]', requested 'float64\[\] \[2\.0\]'\)"),
    (dict(task=ChainSwingup(lg.systems.pendulum(gear=6.0), dt=0.05, horizon=20, noise=0.5)),
     r"\(task\.chain\.motors\[0\]\.gear: checkpoint 'float64\[\] \[5\.0\]', requested 'float64\[\] \[6\.0\]'\)"),
    (dict(task=dataclasses.replace(TASK, dt=0.04)), r"\(task\.dt: checkpoint 0\.05, requested 0\.04\)"),
    (dict(task=dataclasses.replace(TASK, noise=0.4)), r"\(task\.noise: checkpoint 0\.5, requested 0\.4\)"),
    (dict(task=dataclasses.replace(TASK, substeps=2)), r"\(task\.substeps: checkpoint 1, requested 2\)"),
    (dict(task=dataclasses.replace(TASK, solver=lg.SemiImplicitEuler())),
     r"\(task\.solver: checkpoint 'RK4', requested 'SemiImplicitEuler'\)"),
    (dict(policy=tiny_gru(TASK)), r"another task or policy \(.*policy: checkpoint 'MLPPolicy', requested 'GRUPolicy'"),
    (dict(policy=tiny_mlp(TASK, width=8)), r"another task or policy \(policy_parameters: checkpoint"),
    (dict(seed=2), r"written with seed 7, requested seed 2"),
])
def test_resume_refuses_another_run(run, change, message):
    with pytest.raises(checkpoint.CheckpointError, match=message):
        _resume(run[0], **change)


@pytest.mark.parametrize("task, policy, message", [
    (pendulum_swingup(horizon=20, noise=0.5, bodies="brax_v1"), None,
     r"another task or policy \(bodies: checkpoint None, given 'brax_v1'; task\.bodies: checkpoint None, given"),
    (ChainSwingup(lg.systems.pendulum(gear=5.0, length=1.5), dt=0.05, horizon=20, noise=0.5), None,
     r"task\.chain\.bodies\[0\]\.tip: checkpoint 'float64\[3\] \[0\.0, 0\.0, -1\.0\]', "  # the link's length
     r"given 'float64\[3\] \[0\.0, 0\.0, -1\.5\]'"),
    (pendulum_swingup(horizon=20, noise=0.5, trig=True), None, r"observation_size: checkpoint 2, given 3"),
    (TASK, tiny_mlp(TASK, width=8), r"policy_parameters: checkpoint"),
])
def test_load_refuses_another_task_or_policy(run, task, policy, message):
    with pytest.raises(checkpoint.CheckpointError, match=message):
        optim.load(run[0], task, tiny_mlp(task) if policy is None else policy)


def test_resume_a_checkpoint_written_before_a_config_field_existed(run, tmp_path):
    """A config field added later (``upright_starts``) matches an older checkpoint at its default, and only then."""
    path, _, _, state = run
    head = checkpoint.read_header(path)
    old = tmp_path / "old.eqx"
    config = {k: v for k, v in head["config"].items() if k != "upright_starts"}
    checkpoint.save(old, state, **{**head, "config": config})
    assert states_equal(_resume(old).state, state)  # all its iterations done: the checkpoint's state
    with pytest.raises(checkpoint.CheckpointError, match=r"upright_starts: checkpoint None, requested 0\.5"):
        _resume(old, config=dataclasses.replace(CFG, upright_starts=0.5))


def test_damaged_and_foreign_files_are_refused(run, tmp_path):
    path, task, policy, _ = run
    data = path.read_bytes()
    header, payload = data.split(b"\n", 1)
    head = json.loads(header)
    flipped = bytearray(data)
    flipped[len(header) + 1 + len(payload) // 2] ^= 0x01  # one bit inside the state
    undigested = {k: v for k, v in head.items() if k != "digest"}
    digest = r"is corrupt: its content does not match the digest its header records"
    files = {
        "cut": (data[: len(data) - 40], digest),
        "long": (data + b"\x00" * 8, digest),
        "flip": (bytes(flipped), digest),
        "edited": (json.dumps(dict(head, history=[dict(head["history"][0], best_return=1e9)] + head["history"][1:]))
                   .encode() + b"\n" + payload, digest),  # the header's history, its digest kept
        "cut, written before the digest": (json.dumps(undigested).encode() + b"\n" + payload[:-40],
                                           r"is corrupt \(its state does not deserialise"),
        "junk": (b"\x00\xffnot a checkpoint", r"is not a lagrange checkpoint \(unreadable header\)"),
        "json": (b'{"format": "other"}\n', r"is not a lagrange checkpoint \(header format is"),
        "v1": (json.dumps(dict(head, version=1)).encode() + b"\n" + payload,
               r"has checkpoint format version 1; this code reads version 2"),
        "v99": (json.dumps(dict(head, version=99)).encode() + b"\n" + payload, r"format version 99"),
        "config": (json.dumps(dict(head, config=dict(head["config"], later_field=1))).encode() + b"\n" + payload,
                   r"its config cannot be rebuilt \(config fields \['later_field'\] are not fields of CEAPGConfig\)"),
    }
    for name, (content, message) in files.items():
        bad = tmp_path / f"{name}.eqx"
        bad.write_bytes(content)
        with pytest.raises(checkpoint.CheckpointError, match=message):
            optim.load(bad, task, policy)
        if name == "config":  # a resume compares the configs instead of rebuilding one
            message = r"different config \(later_field: checkpoint 1, requested None\)"
        with pytest.raises(checkpoint.CheckpointError, match=message):
            _resume(bad)


def test_edited_counters_and_nan_states_are_refused(run, tmp_path):
    """A checkpoint whose digest is right but whose iteration counter is negative or disagrees with its header or
    its history, or whose state holds a NaN (which a run never saves), is refused by a resume and by a load."""
    path, task, policy, state = run
    head = checkpoint.read_header(path)
    cases = {
        "negative": (state._replace(iteration=jnp.asarray(-3, jnp.int32)), dict(iteration=-3, history=[]),
                     r"inconsistent iteration count \(state -3, header -3, history of 0 iterations"),
        "header": (state, dict(iteration=5), r"inconsistent iteration count \(state 2, header 5, history of 2"),
        "history": (state, dict(history=head["history"][:1]), r"\(state 2, header 2, history of 1 iterations"),
        "nan": (state._replace(mean=state.mean.at[3].set(jnp.nan)), {}, r"holds a NaN in its state \(\.mean\)"),
    }
    for name, (bad_state, changes, message) in cases.items():
        bad = tmp_path / f"{name}.eqx"
        checkpoint.save(bad, bad_state, **{**head, **changes})
        with pytest.raises(checkpoint.CheckpointError, match=message):
            _resume(bad)
        with pytest.raises(checkpoint.CheckpointError, match=message):
            optim.load(bad, task, policy)


def test_a_checkpoint_from_before_the_digest_and_the_task_fields_resumes(run, tmp_path):
    """Written before the header had a digest and the identity the task's fields: still read, compared on what it
    records."""
    path, task, policy, state = run
    header, payload = path.read_bytes().split(b"\n", 1)
    head = json.loads(header)
    del head["digest"]
    head["identity"] = {k: v for k, v in head["identity"].items() if not k.startswith("task.")}
    old = tmp_path / "old.eqx"
    old.write_bytes(json.dumps(head).encode() + b"\n" + payload)
    assert states_equal(_resume(old).state, state) and states_equal(optim.load(old, task, policy)[1], state)


def test_a_checkpoint_path_that_cannot_be_written_is_refused_before_any_work(tmp_path):
    cfg, task, policy, _ = small_problem("APGConfig")
    (tmp_path / "file").write_text("not a folder")
    for path, message in ((tmp_path, r"checkpoint '.*' is a folder; give a file path"),
                          (tmp_path / "file" / "run.eqx", r"cannot be written: its folder '.*file' is not a folder")):
        with pytest.raises(ValueError, match=message):
            optim.train(cfg, task, policy, RUN_KEY, checkpoint=path, progress=False)
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(ValueError, match=r"cannot be written: its folder '.*locked' is not writable"):
            optim.train(cfg, task, policy, RUN_KEY, checkpoint=locked / "run.eqx", progress=False)
