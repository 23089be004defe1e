"""Tests run in 64-bit floats with strict dtype promotion; the library itself never sets this.

They also compile with XLA's classic CPU fusion emitters, one code-generation thread per compilation and LLVM's
optimisation level 0 (``TEST_XLA_FLAGS``, appended to any ``XLA_FLAGS`` already set, and inherited by the examples and
scripts the tests start). Compilation is most of the suite's time (research/LOG.md, "CI time"): the default MLIR
fusion emitters compile each fusion more slowly, two xdist workers already keep both cores busy, and LLVM's optimising
passes cost more compile time than they save in the tests' short runs (the whole suite 904 s against 1258-1398 s on
two cores). None of the flags turns on fast-math: every operation is IEEE's either way, but the machine code differs,
so two differently fused programs may differ in their last bits (the one test that compared two programs bit for
bit compares them to two ulps). Users run with XLA's defaults, and the benchmarks measure with them."""

import os

TEST_XLA_FLAGS = (
    "--xla_cpu_use_fusion_emitters=false --xla_cpu_parallel_codegen_split_count=1 --xla_backend_optimization_level=0"
)
os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {TEST_XLA_FLAGS}".strip()

import jax  # noqa: E402  (XLA reads XLA_FLAGS when its CPU client starts, after the line above)

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")
