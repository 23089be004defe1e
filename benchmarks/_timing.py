"""Shared timing helper of the benchmarks: warm up, then the median (or minimum) of repeats."""

from __future__ import annotations

import statistics
import time

import jax


def median_time(fn, *args, repeats: int = 5, min_time: float = 0.05, warmup: int = 1, best: bool = False) -> float:
    """Median (``best``: minimum) seconds per call of ``fn(*args)`` after ``warmup`` calls. Each repeat runs the call
    often enough to last at least ``min_time`` seconds, so that short calls are not timer noise; the minimum is the
    robust choice on a machine shared with other work."""
    for _ in range(warmup):
        jax.block_until_ready(fn(*args))
    t = time.perf_counter()
    jax.block_until_ready(fn(*args))
    one = max(time.perf_counter() - t, 1e-7)
    number = max(1, int(min_time / one))
    samples = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(number):
            out = fn(*args)
        jax.block_until_ready(out)
        samples.append((time.perf_counter() - t) / number)
    return min(samples) if best else statistics.median(samples)
