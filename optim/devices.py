"""One JAX device per CPU core, so that CE-APG's candidates (sharded over ``jax.devices()``) use every core.

XLA's CPU backend runs one device's program on a thread pool, but a CE-APG iteration is a long sequential scan of
small batched operations that that pool barely parallelises: on two cores one device keeps about one core busy.
Splitting the host into one device per core and sharding the candidate axis over them (which
every algorithm of :mod:`optim` does for any device count) runs the candidates on every core. Measured on
the project's 2-core machine, acrobot, 24 candidates x 10 APG steps x 2 episodes x 500 steps: 0.80 s per iteration
on one device, 0.36 s on two, 0.43 s on four, 0.58 s on eight. One iteration equals the single-device result to
round-off (``tests/optim/test_devices.py::test_sharded_equals_single_device``); over a long run chaotic training
amplifies that round-off, so a seed's outcome can differ with the device count (docs, "Training").

Call :func:`use_cpu_cores` before the first JAX computation (importing ``jax``, ``lagrange`` or ``optim`` is
fine). It changes only the CPU platform: on a machine with a GPU, ``jax.devices()`` is still the GPU.
"""

from __future__ import annotations

import os
import warnings

__all__ = ["use_cpu_cores", "cpu_core_count", "population_mesh", "shard_count", "jit_replicated"]


def cpu_core_count() -> int:
    """The CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def use_cpu_cores(n: int | None = None) -> int:
    """Expose ``n`` CPU devices to JAX (default: one per core); returns the CPU device count in effect.

    A device count already given in ``XLA_FLAGS`` (``--xla_force_host_platform_device_count``) wins. If JAX has
    already run a computation the count can no longer change: this warns and returns the current count.

    Args:
        n: the CPU devices, an integer >= 1; None: one per core (:func:`cpu_core_count`).

    Raises:
        ValueError: for another ``n``.
    """
    import jax

    if n is None:
        n = cpu_core_count()
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"use_cpu_cores: n must be an integer >= 1 (CPU devices), got {n!r}")
    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        return len(jax.devices("cpu"))
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:
        have = len(jax.devices("cpu"))
        if have != n:
            warnings.warn(f"use_cpu_cores({n}) called after JAX started: keeping its {have} CPU device(s)",
                          stacklevel=2)
        return have
    return n


def population_mesh(size: int, *, divides: bool = False):
    """A 1-D ``"population"`` mesh over at most ``size`` of ``jax.devices()`` (every device JAX sees: the CPU devices of
    :func:`use_cpu_cores`, the GPUs, or every host's devices after ``jax.distributed.initialize()``); more devices
    than population members (candidates, runs, environments) would only run padding.

    Args:
        size: the population's members.
        divides: use the largest device count that divides ``size`` (a population that is not padded).
    """
    import jax
    import numpy as np
    from jax.sharding import Mesh

    return Mesh(np.asarray(jax.devices()[:shard_count(size, divides=divides)]), ("population",))


def shard_count(size: int, *, divides: bool = False) -> int:
    """How many devices a population is sharded over (:func:`population_mesh`).

    Args:
        size: the population's members.
        divides: the largest count that divides ``size``.
    """
    import jax

    n = min(len(jax.devices()), max(1, size))
    while divides and size % n:
        n -= 1
    return n


def jit_replicated(update, replicated, compiler_options=None):
    """``jax.jit(update)`` for a state that lives replicated on every device: the state is placed there before each
    call, which keeps one jit cache entry.

    Args:
        update: ``update(state) -> (state, metrics)``.
        replicated: a ``NamedSharding`` with an empty ``PartitionSpec``.
        compiler_options: XLA's options for the program (:func:`lagrange.compiler_options` of the task's model).
    """
    import jax

    jitted = jax.jit(update, out_shardings=replicated, compiler_options=compiler_options)

    def update_replicated(state):
        return jitted(jax.device_put(state, replicated))

    return update_replicated
