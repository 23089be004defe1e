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

# The end-to-end tests at the top of tests/ (scripts, examples and docs run in subprocesses: 10-60 s each, most of the
# slowest 15) are collected last; with two xdist workers a long one left for the end runs alone while the other worker
# idles. Running them first (longest files first) lets the short tests fill in around them.
FIRST = ("test_gpu_benchmark.py", "test_examples.py", "test_docs.py", "test_readme.py", "test_stability_benchmark.py")


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.path.name
        return FIRST.index(name) if item.path.parent.name == "tests" and name in FIRST else len(FIRST)

    items.sort(key=rank)  # stable: the order within each file, and of the rest, is kept
