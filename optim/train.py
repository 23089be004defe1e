"""The one host loop: :func:`train` runs any algorithm's :class:`optim.Trainer` with a progress bar, an atomic
checkpoint after every iteration, resume, optional deterministic evaluations, and one learning-curve record."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from typing import Any, NamedTuple
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import PRNGKeyArray

from lagrange.compile import compiler_options
from optim import checkpoint as ckpt
from optim.base import AlgorithmConfig, Trainer, comparable_config, config_difference, config_from_dict, config_to_dict
from optim.bptt import flatten_policy
from optim.episode import evaluate

__all__ = ["train", "load", "TrainResult", "describe"]


class TrainResult(NamedTuple):
    """What :func:`train` returns.

    Attributes:
        state: the final training state.
        history: one dict of floats per iteration: the algorithm's metrics, ``iteration``, cumulative ``env_steps``
            and ``elapsed`` seconds (training only; evaluations excluded).
        curve: one dict per deterministic evaluation (``iteration``, ``env_steps``, ``elapsed``, ``return``,
            ``return_std``, ``balanced``); empty without ``eval_every``.
        trainer: the :class:`optim.Trainer` that ran, for ``trainer.policy(state)``.
    """

    state: Any
    history: list[dict]
    curve: list[dict]
    trainer: Trainer


def describe(task, policy) -> dict:
    """What a checkpoint records of the task and the policy, and a resume or :func:`load` must match.

    Args:
        task: the task trained on.
        policy: the policy module.

    Returns:
        A JSON-able dict: the task's class, body set, horizon and sizes, the policy's class and parameter count, and
        every field of the task and its chain under ``"task.<field>"`` (``"task.chain.mass"``, ``"task.dt"``,
        ``"task.solver"``, ...): a number or string as it is, an array as its dtype, shape and values (a SHA-256 of
        its bytes beyond 16 entries).
    """
    return {"task": type(task).__name__, "bodies": getattr(task, "bodies", None), "horizon": int(task.horizon),
            "observation_size": int(task.observation_size), "action_size": int(task.action_size),
            "policy": type(policy).__name__, "policy_parameters": int(flatten_policy(policy)[0].size),
            **_fields(task, "task")}


def _fields(obj, name: str) -> dict:
    """``{name(.field)*: value}`` of ``obj``'s fields, recursively through modules, dataclasses and tuples."""
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return {name: obj}
    if isinstance(obj, (np.ndarray, np.generic, jax.Array)):
        a = np.asarray(obj)
        head = f"{a.dtype}{list(a.shape)}"
        if a.size > 16:
            return {name: f"{head} sha256 {hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]}"}
        return {name: f"{head} {a.ravel().tolist()}"}
    if isinstance(obj, (tuple, list)):
        return {k: v for i, item in enumerate(obj) for k, v in _fields(item, f"{name}[{i}]").items()}
    if dataclasses.is_dataclass(obj):
        out = {name: type(obj).__name__}
        for f in dataclasses.fields(obj):
            out.update(_fields(getattr(obj, f.name), f"{name}.{f.name}"))
        return out
    return {name: type(obj).__qualname__}


def _identity_difference(saved: dict, identity: dict, *, now_as: str) -> str:
    """The identity fields that differ; a task field (``task.*``) a checkpoint written before such fields were
    recorded lacks is not compared."""
    now = {k: v for k, v in identity.items() if k in saved or not k.startswith("task.")}
    return config_difference(saved, now, saved_as="checkpoint", now_as=now_as)


def train(config: AlgorithmConfig, task, policy, key: PRNGKeyArray, *, checkpoint: str | os.PathLike | None = None,
          resume: bool = False, seed: int | None = None, progress: bool = True, eval_every: int | None = None,
          eval_episodes: int = 16, eval_key: PRNGKeyArray | None = None,
          objective: Callable | None = None) -> TrainResult:
    """Train ``policy`` on ``task`` with the algorithm ``config`` describes: the one entry point of every algorithm.

    Runs ``config.iterations`` jitted iterations of ``config.make_trainer(task, policy, objective=objective)`` from
    ``key`` (iteration ``i`` draws from ``fold_in(key, i)``) under a tqdm bar. With ``checkpoint`` (a path) the state,
    config, task/policy description (:func:`describe`), ``seed``, history and curve are written atomically after every
    iteration (by process 0 only, when ``jax.distributed`` runs several); with ``resume`` an existing checkpoint there
    is continued: with the same config a resumed run ends at exactly the state of an uninterrupted one. It must have
    been written with the same config (``iterations`` may grow, which changes a learning-rate schedule that spans
    them; a field added to a config class since then must have its default), task, policy and ``seed``, else
    :class:`optim.checkpoint.CheckpointError` says what differs. With ``eval_every = k`` the deterministic policy
    (``trainer.policy(state)``) is evaluated on ``eval_episodes`` starts drawn from ``eval_key`` (the same each time;
    default ``PRNGKey(10_000)``) before training, every ``k`` iterations and after the last.

    Args:
        config: the algorithm's settings.
        task: the task to train on.
        policy: the policy module, its architecture.
        key: the run's PRNG key.
        checkpoint: the checkpoint file, or None for none; checked to be writable before any work.
        resume: continue the checkpoint at ``checkpoint`` if there is one.
        seed: recorded in the checkpoint, and compared on resume.
        progress: show a progress bar.
        eval_every: evaluate every this many iterations, >= 1; None: never.
        eval_episodes: episodes of each evaluation.
        eval_key: the PRNG key of the evaluations' starts.
        objective: the loss of an episode batch (:meth:`optim.AlgorithmConfig.make_trainer`).

    Returns:
        A :class:`TrainResult`.

    Raises:
        ValueError: a bad ``eval_every``, or a ``checkpoint`` that cannot be written.
        optim.checkpoint.CheckpointError: a checkpoint that cannot be resumed, naming what differs or is damaged.
        FloatingPointError: an iteration that left a NaN in the training state (not checkpointed; the file keeps
            the iteration before).
    """
    from tqdm.auto import tqdm

    if eval_every is not None and (isinstance(eval_every, bool) or not isinstance(eval_every, int) or eval_every < 1):
        raise ValueError(f"train: eval_every must be None or an integer >= 1, got {eval_every!r}")
    if isinstance(eval_episodes, bool) or not isinstance(eval_episodes, int) or eval_episodes < 1:
        raise ValueError(f"train: eval_episodes must be an integer >= 1, got {eval_episodes!r}")
    key = _raw_key(key)
    _check_policy(task, policy)
    if checkpoint is not None:  # before any work: a path that cannot be written would fail after the first iteration
        ckpt.check_writable(checkpoint)
    trainer = config.make_trainer(task, policy, objective=objective)
    iterations = config.iterations
    cfg_dict = config_to_dict(config)
    identity = describe(trainer.task, policy)
    state = trainer.init(key)
    history: list[dict] = []
    curve: list[dict] = []
    if resume and checkpoint is not None and os.path.exists(checkpoint):
        state, head = _resume(checkpoint, state, config, identity, seed)
        history, curve = head.get("history", []), head.get("curve", [])
    start = int(state.iteration)
    if start > iterations:
        raise ckpt.CheckpointError(
            f"{checkpoint} has {start} iterations done, more than the config's iterations={iterations}: ask for "
            f"iterations >= {start}, or start afresh without resume")
    env_steps = history[-1]["env_steps"] if history else 0.0
    elapsed = history[-1]["elapsed"] if history else 0.0
    eval_key = jax.random.PRNGKey(10_000) if eval_key is None else eval_key
    if eval_every is not None:
        run_eval = jax.jit(lambda s: evaluate(trainer.task, *trainer.policy(s), eval_key, eval_episodes),
                           compiler_options=compiler_options(trainer.task.chain))

    def evaluate_now(i):
        rets, bal = jax.device_get(run_eval(state))
        curve.append({"iteration": i, "env_steps": env_steps, "elapsed": elapsed, "return": float(np.mean(rets)),
                      "return_std": float(np.std(rets)), "balanced": float(np.mean(bal))})

    if eval_every is not None and not curve:
        evaluate_now(start)
    shown: dict[str, float] = {}
    bar = tqdm(total=iterations, initial=start, disable=not progress, unit="it", dynamic_ncols=True)
    for it in range(start, iterations):
        t0 = time.perf_counter()
        state, metrics = trainer.update(state)
        metrics = _host_metrics(jax.device_get(metrics))
        elapsed += time.perf_counter() - t0
        env_steps += metrics.pop("env_steps")
        metrics.update(iteration=it + 1, env_steps=env_steps, elapsed=elapsed)
        bad = ckpt.nan_leaves(state)
        if bad:  # never checkpointed: the last checkpoint keeps the iteration before
            raise FloatingPointError(
                f"train: iteration {it + 1} left a NaN in the training state ({', '.join(bad)}); "
                + (f"{os.fspath(checkpoint)} keeps iteration {it}. " if checkpoint is not None else "")
                + "Look for a non-finite observation, reward or parameter in the task and the policy")
        history.append(metrics)
        note = _nonfinite_note(metrics)
        if note:
            bar.write(f"iteration {it + 1}: {note}")
        if eval_every is not None and ((it + 1) % eval_every == 0 or it + 1 == iterations):
            evaluate_now(it + 1)
        if checkpoint is not None and jax.process_index() == 0:  # one writer when several hosts run the program
            ckpt.save(checkpoint, state, config=cfg_dict, identity=identity, seed=seed, iteration=it + 1,
                      history=history, curve=curve)
        shown.update({k: metrics[k] for k in trainer.summary if np.isfinite(metrics.get(k, np.nan))})
        if curve:
            shown["eval_return"] = curve[-1]["return"]
        bar.set_postfix({k: f"{v:.4g}" for k, v in shown.items()} | {"steps": f"{env_steps:.2e}"}, refresh=False)
        bar.update(1)
    bar.close()
    return TrainResult(state, history, curve, trainer)


def _raw_key(key):
    """One PRNG key as raw ``(2,)`` uint32 key data (a typed key's data: what a checkpoint can store)."""
    if jax.dtypes.issubdtype(getattr(key, "dtype", np.float64), jax.dtypes.prng_key) and np.shape(key) == ():
        key = jax.random.key_data(key)
    if getattr(key, "dtype", None) != np.uint32 or np.shape(key) != (2,):
        raise ValueError(f"train: key must be one PRNG key (jax.random.PRNGKey(seed) or jax.random.key(seed)), got "
                         f"{key!r:.80}")
    return key


def _check_policy(task, policy) -> None:
    """The policy takes the task's observation and returns its action: checked on shapes (nothing computed)."""
    name = type(policy).__name__
    try:
        obs = jax.ShapeDtypeStruct((task.observation_size,), jnp.result_type(float))
        action, _ = jax.eval_shape(lambda o: policy(o, policy.initial_state(), True), obs)
    except Exception as err:  # noqa: BLE001 -- any failure here is a policy that does not fit the task
        why = str(err).splitlines()[0].rstrip(".") if str(err) else type(err).__name__
        raise ValueError(f"train: the policy ({name}) does not take the task's observation of shape "
                         f"({task.observation_size},): {why}. Build it for the task: {name}.for_task(task, ...)") \
            from None
    if action.shape != (task.action_size,):
        raise ValueError(f"train: the policy ({name}) returns actions of shape {action.shape}, the task takes "
                         f"({task.action_size},). Build it for the task: {name}.for_task(task, ...)")


def _host_metrics(metrics: dict) -> dict:
    """An iteration's metrics for the history: scalars as floats, a boolean mask over the population members as the
    list of the members' indices where it is true."""
    out = {}
    for k, v in metrics.items():
        v = np.asarray(v)
        out[k] = np.flatnonzero(v).tolist() if v.ndim else float(v)
    return out


def _nonfinite_note(metrics: dict) -> str:
    """What went non-finite in an iteration, naming the members, or ``""``."""
    parts = []
    if metrics.get("nonfinite", 0):
        parts.append(f"{int(metrics['nonfinite'])} update(s) or candidate(s) went non-finite (skipped, or fitness "
                     f"-inf)")
        if metrics.get("nonfinite_members"):
            parts[-1] += f"; members (candidates or runs, from 0): {metrics['nonfinite_members']}"
    if metrics.get("nonfinite_envs"):
        parts.append(f"environments {metrics['nonfinite_envs']} went non-finite and restarted")
    return "; ".join(parts)


def _check_iterations(path, state, head: dict) -> None:
    """The iteration counter of a checkpoint's state agrees with its header and its history."""
    done = int(state.iteration)
    history = head.get("history")
    if done < 0 or head.get("iteration", done) != done or (isinstance(history, list) and len(history) != done):
        raise ckpt.CheckpointError(
            f"{path} has an inconsistent iteration count (state {done}, header {head.get('iteration')!r}, history of "
            f"{len(history) if isinstance(history, list) else None} iterations; all must be the same integer >= 0). "
            f"Start the run afresh without resume")


def _resume(path, like, config: AlgorithmConfig, identity: dict, seed):
    head = ckpt.read_header(path)
    saved = head.get("config")
    if not isinstance(saved, dict):
        raise ckpt.CheckpointError(f"{path} has no config in its header")
    want = comparable_config(config, saved)
    want["iterations"] = saved.get("iterations")  # the iteration count may grow on resume
    # config, task/policy and seed first: a state of another shape would otherwise read as a corrupt file
    if saved != want:
        detail = config_difference(saved, want, saved_as="checkpoint", now_as="requested")
        raise ckpt.CheckpointError(f"{path} was written with a different config ({detail})")
    detail = _identity_difference(head.get("identity") or {}, identity, now_as="requested")
    if detail:
        raise ckpt.CheckpointError(f"{path} was written for another task or policy ({detail})")
    if seed is not None and head.get("seed") != seed:
        raise ckpt.CheckpointError(f"{path} was written with seed {head.get('seed')!r}, requested seed {seed}")
    state, head = ckpt.load(path, like, config=want)
    _check_iterations(path, state, head)
    return state, head


def load(path: str | os.PathLike, task, policy, *, objective: Callable | None = None):
    """Read a checkpoint written by :func:`train`; the config comes from the file's header.

    Args:
        path: the checkpoint file.
        task: the task it was trained with (checked against the header).
        policy: the policy module it was trained with (checked).
        objective: the objective it was trained with, if not the default.

    Returns:
        ``(trainer, state, header)``.

    Raises:
        optim.checkpoint.CheckpointError: a damaged file (its digest, its iteration counter, a NaN), another format,
            or another task or policy, naming what differs.
    """
    head = ckpt.read_header(path)
    try:
        config = config_from_dict(head.get("config") or {})
    except (TypeError, ValueError) as err:
        raise ckpt.CheckpointError(f"{path}: its config cannot be rebuilt ({err})") from None
    trainer = config.make_trainer(task, policy, objective=objective)
    detail = _identity_difference(head.get("identity") or {}, describe(trainer.task, policy), now_as="given")
    if detail:
        raise ckpt.CheckpointError(f"{path} was written for another task or policy ({detail})")
    state, head = ckpt.load(path, trainer.init(jax.random.PRNGKey(0)))
    _check_iterations(path, state, head)
    return trainer, state, head
