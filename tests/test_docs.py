"""The code the documentation shows runs as printed and gives what the pages say it gives."""

import re
import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np

import lagrange as lg
from lagrange.planar.lower import lower as planar

DOCS = Path(__file__).resolve().parent.parent / "docs"


def blocks(page: str) -> list[str]:
    found = re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), re.S)
    assert found, f"docs/{page} has no python block"
    return found


def run_page(page: str, scope: dict | None = None) -> dict:
    """Every python block of ``page``, in order, in one namespace (as a reader runs them); a deprecated name of
    lagrange's that the page uses (``Tree.n``, a renamed solver: their ``DeprecationWarning``) fails it."""
    scope = {} if scope is None else scope
    with warnings.catch_warnings():
        warnings.filterwarnings("error", r"(Tree\.\w+ is deprecated|lagrange\.\w+ is renamed)", DeprecationWarning)
        for i, code in enumerate(blocks(page)):
            exec(compile(code, f"docs/{page}, python block {i}", "exec"), scope)
    return scope


def test_getting_started_runs_and_shapes_are_as_stated():
    s = run_page("getting-started.md")
    # "Define a chain": chain.nq = chain.nv = 4, chain.m is 3, M is (4, 4), one mass gradient per link
    assert (s["M"].shape, s["dmass"].shape) == ((4, 4), (4,))
    assert np.all(np.isfinite(np.asarray(s["dmass"])))
    # "Trees, springs, contact and limits": a cart carrying two pendulums side by side, a planar Tree
    assert s["tree"].parents == (-1, 0, 0) and s["tree"].planar and isinstance(s["tree"], lg.Tree)
    assert planar(s["tree"]).children(0) == (1, 2)
    assert s["points"].shape == (4, 3) and np.all(np.asarray(s["points"])[:, 1] == 0)  # (x, 0, z) rows
    # "Simulate": (301, 2) states and (300, 1) controls for 300 intervals of the acrobot
    assert s["traj"].q.shape == (301, 2) and s["traj"].u.shape == (300, 1)
    # "Gradients": a Chain of parameter gradients, and one per control
    assert isinstance(s["dchain"], lg.Chain) and s["dus"].shape == (100, 1)
    assert np.all(np.isfinite(np.asarray(s["dchain"].mass)))
    # the stated identity: inverse dynamics of the forward dynamics' q̈ gives B u
    chain = s["chain"]
    q, qd, u = jnp.array([0.3, -0.2]), jnp.array([1.0, 0.5]), jnp.array([0.7])
    tau = lg.inverse_dynamics(chain, q, qd, lg.forward_dynamics(chain, q, qd, u))
    np.testing.assert_allclose(tau, lg.actuation_matrix(chain) @ u, rtol=0, atol=1e-12)


def test_home_page_snippet_runs():
    s = run_page("index.md")
    assert s["traj"].q.shape == (501, 2) and s["dq_dm"].shape == (2,)


def test_solvers_page_snippet_runs():
    scope = {"chain": lg.systems.acrobot(), "q0": jnp.array([0.5, 0.0]), "qd0": jnp.zeros(2),
             "us": jnp.zeros((20, 1))}
    exec("import diffrax\nimport lagrange as lg", scope)
    run_page("solvers.md", scope)


def test_conventions_biped_is_as_described():
    s = run_page("conventions.md")
    biped = s["biped"]
    assert biped.parents == (-1, 0, 1, 2, 3, 2, 5) and planar(biped).children(2) == (3, 5)
    assert planar(biped).path(6) == (0, 1, 2, 5, 6) and not planar(biped).serial
    # the back thigh's attach point (-0.1, 0) in the upright torso's frame is x = +0.1 in the world; the feet
    np.testing.assert_allclose(np.asarray(lg.positions(biped, jnp.zeros(7))[5, ::2]), [0.1, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.asarray(s["tips"])[[4, 6]], [[0.0, -0.8], [0.1, -0.8]], atol=1e-15)


def test_contact_page_snippet_runs():
    s = run_page("contact.md")
    traj, biped = s["traj"], s["biped"]
    assert traj.q.shape == (301, 7) and planar(biped).contact_links == (4, 6) and planar(biped).limited == (3, 4, 5, 6)
    assert float(jnp.min(traj.q[:, 1])) < 0.0  # it landed: the feet sank below their starting height's 10 cm
    assert s["kinetic"].shape == s["potential"].shape == (301,)
    assert np.isfinite(float(s["dke"])) and float(s["dke"]) != 0.0  # the contact is felt


def test_spatial_trees_page_snippets_run():
    s = run_page("trees3d.md")
    tree, traj = s["tree"], s["traj"]
    assert (tree.nq, tree.nv, tree.m) == (12, 10, 1) and traj.q.shape == (201, 12) and traj.qd.shape == (201, 10)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(traj.q)[:, 3:7], axis=1), 1.0, rtol=0, atol=1e-14)
    assert isinstance(s["humanoid"], lg.Tree) and s["humanoid"].nv == 23
