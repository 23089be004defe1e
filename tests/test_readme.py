"""The README's two commands are the ones CI and users run."""

from pathlib import Path

from lagrange.planar.lower import lower as planar
from lagrange.tasks.base import joint_kinds

ROOT = Path(__file__).resolve().parent.parent
TEST_COMMAND = ('python3 -m venv .venv && . .venv/bin/activate && pip install uv && uv pip install -e ".[test]" '
                '&& python -m pytest -n 2 --dist worksteal tests')
RUN_COMMAND = "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && python examples/acrobot_swingup.py"


def test_ci_runs_exactly_the_readme_test_command_then_lints_and_builds_the_docs():
    readme = (ROOT / "README.md").read_text()
    lines = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert TEST_COMMAND in readme
    assert lines[-3:] == [TEST_COMMAND, "ruff check .", 'uv pip install -e ".[docs]" && mkdocs build --strict']


def test_readme_shows_the_main_job():
    assert RUN_COMMAND in (ROOT / "README.md").read_text()
    assert (ROOT / "examples" / "acrobot_swingup.py").exists()


def test_readme_chain_example_runs():
    """The 'Define a chain' snippet runs as printed and gives what it says it gives."""
    import re

    readme = (ROOT / "README.md").read_text()
    code = re.search(r"## Define a chain or a tree\n\n```python\n(.*?)```", readme, re.S).group(1)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert scope["traj"].q.shape == (501, 4)
    assert scope["M"].shape == (4, 4)
    assert scope["dmass"].shape == (4,)
    import numpy as np

    assert np.all(np.isfinite(np.asarray(scope["dmass"])))


def test_readme_tree_example_runs():
    """The tree snippet, run after the chain snippet as a reader runs them: the biped's structure, its feet's contact
    points and limited joints, and a drop onto the ground that lands (the feet sink) and stays finite."""
    import re

    import jax.numpy as jnp
    import numpy as np

    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Define a chain or a tree"):readme.index("Or read one from MJCF")]
    scope: dict = {}
    for code in re.findall(r"```python\n(.*?)```", section, re.S):
        exec(compile(code, "README.md", "exec"), scope)
    biped = scope["biped"]
    assert biped.parents == (-1, 0, 1, 2, 3, 2, 5) and planar(biped).children(2) == (3, 5)
    assert planar(biped).contact_links == (4, 6) and planar(biped).limited == (3, 4, 5, 6) and biped.m == 4
    drop = scope["drop"]
    assert drop.q.shape == (301, 7) and np.all(np.isfinite(np.asarray(drop.q)))
    assert float(jnp.min(drop.q[:, 1])) < 0.0  # it fell 10 cm onto its feet and sank in


def test_readme_mjcf_example_runs():
    """The 'read one from MJCF' snippet loads Gymnasium's inverted double pendulum as printed."""
    import re

    readme = (ROOT / "README.md").read_text()
    code = re.search(r"Or read one from MJCF.*?```python\n(.*?)```", readme, re.S).group(1)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert joint_kinds(scope["pendulum"]) == ("prismatic", "revolute", "revolute") and scope["pendulum"].m == 1
    assert scope["cheetah"].parents == (-1, 0, 1, 2, 0, 4, 5) and scope["cheetah"].m == 6  # torso and two legs
    assert scope["pendulum"].planar and scope["cheetah"].planar
