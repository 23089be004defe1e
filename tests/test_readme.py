"""The README's two commands are the ones CI and users run."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TEST_COMMAND = 'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && python -m pytest -n 2 --dist worksteal tests'
RUN_COMMAND = "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && python examples/acrobot_swingup.py"


def test_ci_runs_exactly_the_readme_test_command_then_builds_the_docs():
    readme = (ROOT / "README.md").read_text()
    lines = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert TEST_COMMAND in readme
    assert lines[-2:] == [TEST_COMMAND, 'pip install -e ".[docs]" && mkdocs build --strict']


def test_readme_shows_the_main_job():
    assert RUN_COMMAND in (ROOT / "README.md").read_text()
    assert (ROOT / "examples" / "acrobot_swingup.py").exists()


def test_readme_chain_example_runs():
    """The 'Define a chain' snippet runs as printed and gives what it says it gives."""
    import re

    readme = (ROOT / "README.md").read_text()
    code = re.search(r"## Define a chain\n\n```python\n(.*?)```", readme, re.S).group(1)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert scope["traj"].q.shape == (501, 4)
    assert scope["M"].shape == (4, 4)
    assert scope["dmass"].shape == (4,)
    import numpy as np

    assert np.all(np.isfinite(np.asarray(scope["dmass"])))


def test_readme_mjcf_example_runs():
    """The 'read one from MJCF' snippet loads Gymnasium's inverted double pendulum as printed."""
    import re

    readme = (ROOT / "README.md").read_text()
    code = re.search(r"Or read one from MJCF.*?```python\n(.*?)```", readme, re.S).group(1)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert scope["chain"].joints == ("prismatic", "revolute", "revolute") and scope["chain"].m == 1
