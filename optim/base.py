"""What every training algorithm is: a typed config of settings, and a :class:`Trainer` of pure functions over a state.

An algorithm's config (:class:`AlgorithmConfig`) holds its settings only; :meth:`AlgorithmConfig.make_trainer` takes the
task and the policy as objects and returns the :class:`Trainer`: ``init(key) -> state`` and ``update(state) -> (state,
metrics)`` (one jitted iteration, randomness from ``fold_in(key, iteration)``), in the manner of optax's
``init``/``update`` pairs and purejaxrl's training functions. :func:`optim.train` is the one host loop that runs any
of them; :func:`scan_train` runs one as a single jittable function.

A config's round trip through JSON (what a checkpoint's header and a run's ``results.json`` record) is here too:
:func:`config_to_dict` and :func:`config_from_dict`, :func:`comparable_config` (a config against one saved before a
field was added) and :func:`config_difference` (the fields that differ, for the errors).
"""

from __future__ import annotations

import abc
import dataclasses
import json
from typing import Any, NamedTuple
from collections.abc import Callable

import jax

__all__ = ["AlgorithmConfig", "Trainer", "scan_train", "config_to_dict", "config_from_dict", "comparable_config",
           "config_difference"]


class Trainer(NamedTuple):
    """An algorithm bound to a task and a policy.

    Attributes:
        init: ``init(key) -> state``; the state holds the run's key and its ``iteration`` count.
        update: ``update(state) -> (state, metrics)``, one jitted iteration; ``metrics`` is a dict of scalars with
            at least ``env_steps`` (simulated control steps of the iteration) and ``nonfinite`` (updates skipped),
            and for a population a ``nonfinite_members`` bool mask (which members went non-finite; SHAC:
            ``nonfinite_envs``).
        policy: ``policy(state, which="best") -> (policy module, normaliser or None)``, the deterministic policy to
            evaluate (``which="mean"``: the search distribution's mean, for the CE methods).
        task: the task it trains on.
        config: its :class:`AlgorithmConfig`.
        summary: the metrics the progress bar shows.
    """

    init: Callable
    update: Callable
    policy: Callable
    task: Any
    config: "AlgorithmConfig"
    summary: tuple[str, ...] = ("best_return", "mean_return")


class AlgorithmConfig(abc.ABC):
    """Base of the algorithms' configs, frozen dataclasses of settings.

    Attributes:
        iterations (int): the run's host iterations (CE iterations, epochs...), every config has it.
    """

    iterations: int

    @abc.abstractmethod
    def make_trainer(self, task, policy, *, objective: Callable | None = None) -> Trainer:
        """The :class:`Trainer` of this algorithm.

        Args:
            task: the task to train on, and the one the trainer evaluates.
            policy: the policy module, its architecture (the algorithm draws the initial weights from the run's key).
            objective: the loss of an episode batch, for the algorithms built on :func:`optim.apg_steps` (default:
                minus the mean return).
        """


def config_to_dict(cfg: AlgorithmConfig) -> dict:
    """The config as the JSON a checkpoint header stores.

    Args:
        cfg: a config (a frozen dataclass).

    Returns:
        ``{"algorithm": <class name>, <field>: <value>, ...}`` as it reads back from JSON (tuples become lists), so it
        compares equal after a round trip.
    """
    return json.loads(json.dumps({"algorithm": type(cfg).__name__, **dataclasses.asdict(cfg)}))


def config_from_dict(saved: dict) -> AlgorithmConfig:
    """The config that :func:`config_to_dict` stored (lists become tuples again).

    Args:
        saved: the dict, with its ``"algorithm"`` (a subclass of :class:`AlgorithmConfig`).

    Raises:
        ValueError: naming an unknown algorithm or unknown fields, or a field out of range.
    """
    if not isinstance(saved, dict):
        raise TypeError(f"a saved config must be a dict (config_to_dict's), got {type(saved).__name__}")
    saved = dict(saved)
    name = saved.pop("algorithm", None)
    classes = {c.__name__: c for c in _subclasses(AlgorithmConfig)}
    if name not in classes:
        raise ValueError(f"unknown algorithm {name!r}; known: {sorted(classes)}")
    cls = classes[name]
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(saved) - fields)
    if unknown:
        raise ValueError(f"config fields {unknown} are not fields of {name}")
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in saved.items()})


def comparable_config(cfg: AlgorithmConfig, saved: dict) -> dict:
    """``cfg`` as a JSON dict (:func:`config_to_dict`) to compare with a ``saved`` one: a field added to the config
    class since ``saved`` was written is left out while it has its default, so older checkpoints stay valid.

    Args:
        cfg: the config asked for now.
        saved: a config dict read back from a checkpoint or a result.
    """
    config = config_to_dict(cfg)
    defaults = json.loads(json.dumps({f.name: f.default for f in dataclasses.fields(cfg)
                                     if f.default is not dataclasses.MISSING}))
    return {k: v for k, v in config.items() if k in saved or k not in defaults or v != defaults[k]}


def config_difference(saved: dict, now: dict, *, saved_as: str, now_as: str) -> str:
    """Every key whose value differs between two dicts (configs, or a checkpoint's identity of its task and policy).

    Args:
        saved: the dict a file recorded.
        now: the dict asked for now.
        saved_as: what to call ``saved`` in the text (``"checkpoint"``).
        now_as: what to call ``now`` (``"requested"``).

    Returns:
        ``key: <saved_as> old, <now_as> new`` for each differing key, sorted, joined by ``; `` (empty when they
        agree; a key one of them lacks reads as None).
    """
    diff = sorted(k for k in set(saved) | set(now) if saved.get(k) != now.get(k))
    return "; ".join(f"{k}: {saved_as} {saved.get(k)!r}, {now_as} {now.get(k)!r}" for k in diff)


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def scan_train(trainer: Trainer, iterations: int | None = None):
    """A whole run as one jittable function, for ``jax.vmap`` over seeds or a run without a host loop.

    Args:
        trainer: the algorithm bound to its task and policy.
        iterations: how many ``trainer.update`` (default: the config's ``iterations``).

    Returns:
        ``train(key) -> (final state, metrics stacked over the iterations)``.
    """
    iterations = trainer.config.iterations if iterations is None else iterations

    def train(key):
        return jax.lax.scan(lambda s, _: trainer.update(s), trainer.init(key), None, iterations)

    return train
