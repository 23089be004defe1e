"""One-off experiments whose numbers the README and docs/balance.md quote, kept so that those numbers can be
regenerated.

Each script is run from the repository root as written in its docstring (``python -m benchmarks.experiments.<name>``).
They patch or copy pieces of the library on purpose (that is the experiment), are not part of the library's API, and
are not run in CI; the maintained benchmarks are the modules one folder up.
"""
