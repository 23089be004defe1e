"""The host loop, public as ``optim.run``: jitted iterations, a tqdm bar, atomic checkpoints, resume."""

from __future__ import annotations

import dataclasses
import json
import os
import time

import jax
import numpy as np

from optim import checkpoint
from optim.apg import config_to_dict


def run(trainer, key, *, iterations: int, ckpt_path: str | None = None, resume: bool = False,
        progress: bool = True, seed: int | None = None):
    """Run ``trainer.update`` until ``iterations`` iterations are done; returns ``(state, history)``.

    ``history`` is a list of per-iteration metric dicts (floats) with cumulative ``env_steps`` and
    ``elapsed`` seconds. The state is checkpointed atomically after every iteration; with
    ``resume`` an existing checkpoint at ``ckpt_path`` (same config) is continued. Iteration ``i``
    draws its randomness from ``fold_in(key, i)``, so a resumed run ends at exactly the state of an
    uninterrupted one.
    """
    from tqdm.auto import tqdm

    config = config_to_dict(trainer.config)
    state = trainer.init(key)
    history: list[dict] = []
    elapsed0 = 0.0
    if resume and ckpt_path and os.path.exists(ckpt_path):
        # The iteration count may grow on resume (it only sets where the learning-rate schedule ends; a
        # resumed run equals an uninterrupted one when it is unchanged); every other field must match.
        # A field added to the config since the checkpoint was written matches when it has its default.
        head = checkpoint.read_header(ckpt_path)
        if isinstance(head.get("config"), dict):
            config_check = comparable_config(trainer.config, head["config"])
            config_check["iterations"] = head["config"].get("iterations")
        else:
            config_check = config
        state, head = checkpoint.load(ckpt_path, state, config=config_check)
        if seed is not None and head.get("seed") != seed:
            raise checkpoint.CheckpointError(
                f"{ckpt_path} was written with seed {head.get('seed')!r}, requested seed {seed}")
        history = head.get("history", [])
        elapsed0 = history[-1]["elapsed"] if history else 0.0
    start = int(state.iteration)
    if start > iterations:
        raise checkpoint.CheckpointError(
            f"{ckpt_path} has {start} iterations done, more than the requested iterations={iterations}: "
            f"ask for iterations >= {start}, or start afresh without resume")
    env_steps = history[-1]["env_steps"] if history else 0.0
    t0 = time.perf_counter()
    bar = tqdm(total=iterations, initial=min(start, iterations), disable=not progress, unit="it",
               dynamic_ncols=True)
    for it in range(start, iterations):
        state, metrics = trainer.update(state)
        metrics = {k: float(v) for k, v in jax.device_get(metrics).items()}
        env_steps += metrics.pop("env_steps")
        metrics.update(iteration=it + 1, env_steps=env_steps, elapsed=elapsed0 + time.perf_counter() - t0)
        history.append(metrics)
        if metrics.get("nonfinite", 0):
            bar.write(f"iteration {it + 1}: {int(metrics['nonfinite'])} candidate(s) went non-finite (fitness -inf)")
        if ckpt_path:
            checkpoint.save(ckpt_path, state, config=config, seed=seed, iteration=it + 1, history=history)
        bar.set_postfix(best=f"{metrics['best_return']:.0f}", mean=f"{metrics['mean_return']:.0f}",
                        steps=f"{env_steps:.2e}", refresh=False)
        bar.update(1)
    bar.close()
    return state, history


def comparable_config(cfg, saved: dict) -> dict:
    """``cfg`` as a JSON dict to compare with a ``saved`` one: a field added to the config class since ``saved``
    was written is left out while it has its default (so old runs and checkpoints stay valid)."""
    config = config_to_dict(cfg)
    defaults = json.loads(json.dumps({f.name: f.default for f in dataclasses.fields(cfg)
                                     if f.default is not dataclasses.MISSING}))
    return {k: v for k, v in config.items() if k in saved or k not in defaults or v != defaults[k]}


def params_equal(a, b) -> bool:
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    return len(la) == len(lb) and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(la, lb))
