"""Tests run in 64-bit floats with strict dtype promotion; the library itself never sets this.

They also compile with XLA's classic CPU fusion emitters and one code-generation thread per compilation
(``TEST_XLA_FLAGS``, appended to any ``XLA_FLAGS`` already set, and inherited by the examples and scripts the tests
start). Compilation is most of the suite's time, and these two flags take about a quarter of it off on two cores
(research/LOG.md, "CI time"): the default MLIR fusion emitters compile each fusion more slowly, and two xdist workers
already keep both cores busy. Neither flag changes what is computed (no fast-math, same optimisation level); users
run with XLA's defaults, and the benchmarks measure with them."""

import os

TEST_XLA_FLAGS = "--xla_cpu_use_fusion_emitters=false --xla_cpu_parallel_codegen_split_count=1"
os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {TEST_XLA_FLAGS}".strip()

import jax  # noqa: E402  (XLA reads XLA_FLAGS when its CPU client starts, after the line above)

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")
