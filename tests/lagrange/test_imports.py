"""The import graph of the ``lagrange`` package, read from the source with ``ast``: one direction of dependency.

Every import counts, at module level or inside a function (a local import only hides a circle from Python's import
machinery; the modules still depend on each other). ``from lagrange import x`` is an edge to ``lagrange.x`` when ``x``
is a module, else to the package (its ``__init__``).

Importing ``lagrange`` or ``lagrange.interop`` loads no optional engine (Brax, Gymnasium, MuJoCo), and importing
the adapters changes no other module (``jax`` above all); both are checked in a fresh interpreter.
"""

import ast
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]  # the repository


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: str) -> dict[str, set[str]]:
    """``{module: the modules of ``package`` it imports}`` for every ``.py`` file under the package."""
    files = sorted((ROOT / package).rglob("*.py"))
    modules = {_module_name(f): f for f in files}
    graph = {}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: from the module's package, up level - 1 packages
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                targets = [f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source
                           for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:  # `import lagrange.chain.x` -> lagrange.chain
                    target = target.rpartition(".")[0]
                if target and target != name:
                    edges.add(target)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A list ``[a, b, ..., a]`` of modules that import each other in a circle, or ``None``."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node):
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_cycle_finder():
    """Positive control: the finder reports a circle, including one through a local import."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


@pytest.mark.parametrize("package, module", [("lagrange", "lagrange.dynamics"), ("policies", "policies.gru"),
                                             ("optim", "optim.ce_apg")])
def test_no_import_circle(package, module):
    graph = import_graph(package)
    assert module in graph and module in graph[package]  # the walk sees the package and what it re-exports
    assert find_cycle(graph) is None, f"modules of {package} import each other in a circle: {find_cycle(graph)}"


def test_dependencies_flow_from_optim_to_policies_to_lagrange():
    """``lagrange`` knows nothing of policies or learning; ``policies`` know nothing of optimisers."""
    for package, forbidden in (("lagrange", ("policies", "optim")), ("policies", ("optim",))):
        for module, path in sorted(_imported_names(package).items()):
            bad = sorted(n for n in path if n.split(".")[0] in forbidden)
            assert not bad, f"{module} imports {bad}"


def _imported_names(package: str) -> dict[str, set[str]]:
    """``{module: every absolute module name it imports}`` for the modules of ``package``."""
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        names = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names.add(node.module)
        out[_module_name(path)] = names
    return out


ALGORITHM = re.compile(r"shac|ce_?apg", re.IGNORECASE)
"""Names of learning algorithms (SHAC, CE-APG) as they would appear in an identifier."""


def code_names(source: str) -> set[str]:
    """Every name the code itself spells: variables, attributes, definitions, arguments, keywords and imported
    modules and aliases (not strings, so not docstrings)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Name):
            names.add(node.id)
        elif isinstance(node, ast.Attribute):
            names.add(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:
            names.add(node.arg)
        elif isinstance(node, ast.alias):
            names |= {node.name, *([node.asname] if node.asname else [])}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_no_module_of_lagrange_names_an_algorithm():
    """The physics and its tasks know nothing of how they are learned: no module, class, function, variable or
    import in ``lagrange`` names SHAC or CE-APG (a docstring may cite "the SHAC authors' environment")."""
    flagged = code_names(textwrap.dedent('''
        from optim.ce_apg import CEAPGConfig
        import optim.shac as s
        def f(shac_env):
            """the SHAC authors' cartpole, trained by CE-APG"""
            return s.x(horizon=CEAPGConfig)
    '''))
    assert {n for n in flagged if ALGORITHM.search(n)} == {"optim.ce_apg", "CEAPGConfig", "optim.shac",
                                                            "shac_env"}  # positive control
    bad = {}
    for path in sorted((ROOT / "lagrange").rglob("*.py")):
        names = {n for n in code_names(path.read_text()) | {_module_name(path)} if ALGORITHM.search(n)}
        if names:
            bad[str(path.relative_to(ROOT))] = sorted(names)
    assert not bad, f"modules of lagrange name an algorithm: {bad}"


def test_chain_imports_no_other_module():
    """``lagrange.chain`` (a builder of a :class:`lagrange.Tree`), the model it builds (``lagrange.model.tree``,
    ``lagrange.model.joints``), its checks (``lagrange.model.checks``) and the laws it holds
    (``lagrange.model.contact``, ``lagrange.model.limits``) are the root of the physics: the parameters and their
    checks, no dynamics and no backend. (``Chain.links`` reads a chain back through the planar backend's lowering,
    ``lagrange.planar.lower``, imported when called; the lowering itself computes no dynamics.)"""
    graph = import_graph("lagrange")
    assert graph["lagrange.chain"] == {"lagrange.model.checks", "lagrange.model.contact", "lagrange.model.limits",
                                       "lagrange.model.tree", "lagrange.model.joints", "lagrange.model.link",
                                       "lagrange.math.scalar", "lagrange.planar.lower"}
    assert not any(m.startswith(("lagrange.dynamics", "lagrange.integrate")) or m.endswith("backend")
                   for m in graph["lagrange.planar.lower"]), graph["lagrange.planar.lower"]
    for module in ("lagrange.model.tree", "lagrange.model.joints"):
        assert all(m.startswith(("lagrange.model.", "lagrange.math.")) for m in graph[module]), graph[module]
    assert graph["lagrange.model.checks"] <= {"lagrange.model.contact", "lagrange.model.limits"}
    assert graph["lagrange.model.contact"] == set() and graph["lagrange.model.limits"] == {"lagrange.model.contact"}


def _run_fresh(code: str, env: dict | None = None) -> None:
    """Run ``code`` in a fresh interpreter (nothing imported yet; ``env``: its environment variables); fails with its
    stderr if it fails."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr


def test_importing_lagrange_and_lagrange_interop_imports_no_optional_engine():
    """Brax, Gymnasium and MuJoCo are loaded by the adapter that needs them, on first use, never before."""
    _run_fresh("""
        import sys
        import lagrange, lagrange.interop, lagrange.interop.mjcf, lagrange.tasks
        assert {"BraxEnv", "GymEnv", "brax_training_compat", "to_mjcf"} <= set(dir(lagrange.interop))
        assert lagrange.interop.to_mjcf is lagrange.interop.mjcf.to_mjcf
        loaded = [m for m in sys.modules if m.split(".")[0] in ("brax", "gymnasium", "mujoco")]
        assert not loaded, loaded
    """)


def test_importing_the_adapters_changes_no_other_module():
    """Importing lagrange.interop.brax and lagrange.interop.gymnasium leaves every module that was loaded before
    as it was (same names bound to the same objects), ``jax`` above all: in particular it does not put back
    ``jax.device_put_replicated``. The engines' own imports come first, so that what they do to ``jax`` (Brax
    imports ``jax.flatten_util``, which binds it on ``jax``) is not counted; the only names allowed to appear
    are the new submodules bound on their parent packages."""
    _run_fresh("""
        import sys
        import jax
        import brax.envs.base, gymnasium, lagrange.tasks, lagrange.kinematics

        def namespaces():  # every loaded module but this script's own (__main__)
            return {name: {k: id(v) for k, v in vars(m).items()}
                    for name, m in list(sys.modules.items()) if m is not None and m is not sys.modules["__main__"]}

        had = {name: hasattr(jax, name) for name in ("device_put_replicated", "device_put_sharded")}
        jax_names, before = sorted(dir(jax)), namespaces()
        import lagrange.interop.brax, lagrange.interop.gymnasium
        after = namespaces()
        assert sorted(dir(jax)) == jax_names, set(dir(jax)) ^ set(jax_names)
        assert {name: hasattr(jax, name) for name in had} == had, had
        changed = {}
        for name, ns in before.items():
            new = {k for k in after[name].keys() - ns.keys() if f"{name}.{k}" not in sys.modules}
            rebound = {k for k in ns if after[name].get(k) != ns[k]}
            if new or rebound:
                changed[name] = (sorted(new), sorted(rebound))
        assert not changed, changed
    """)



def test_the_compiler_options_turn_off_the_ynn_fusions_for_a_tree_only():
    """A spatial tree's program compiled with ``lg.compiler_options(tree)`` holds no YNNPACK fusion (one compiled
    with the defaults does: the option's premise); a chain gets None (the defaults); other backends get None."""
    import jax
    import jax.numpy as jnp

    import lagrange as lg

    tree = lg.Tree([lg.Body(1.0, (0.1, 0.2, 0.3), joints=[lg.Free()]),
                    lg.Body(1.0, (0.1, 0.1, 0.1), (0.0, 0.0, -0.5), joints=[lg.Hinge((0, 1, 0))])])
    assert lg.compiler_options(tree, "cpu") == {"xla_cpu_experimental_ynn_fusion_type": ""}
    assert lg.compiler_options(tree, "gpu") is None and lg.compiler_options(lg.systems.pendulum(), "cpu") is None
    q = jnp.tile(tree.neutral().astype(jnp.float32), (64, 1))
    qd = jnp.ones((64, tree.nv), jnp.float32)
    f = jax.vmap(lambda q, qd: lg.bias_forces(tree, q, qd))

    def fused(options):
        return "__ynn_fusion" in jax.jit(f, compiler_options=options).lower(q, qd).compile().as_text()

    assert fused(None) and not fused(lg.compiler_options(tree))


def test_the_xla_flag_turns_off_the_ynn_fusions_for_every_program_of_a_fresh_process():
    """``YNN_OFF_FLAG`` in ``XLA_FLAGS`` (for programs that others jit: Brax's trainers) is ``YNN_OFF`` for the whole
    process: a tree's program jitted with the defaults holds no YNNPACK fusion there (it does without the flag: the
    test above)."""
    import os

    from lagrange.compile import YNN_OFF, YNN_OFF_FLAG

    assert YNN_OFF_FLAG == "--{}={}".format(*next(iter(YNN_OFF.items())))
    _run_fresh("""
        import jax, jax.numpy as jnp
        import lagrange as lg
        tree = lg.Tree([lg.Body(1.0, (0.1, 0.2, 0.3), joints=[lg.Free()]),
                        lg.Body(1.0, (0.1, 0.1, 0.1), (0.0, 0.0, -0.5), joints=[lg.Hinge((0, 1, 0))])])
        q = jnp.tile(tree.neutral().astype(jnp.float32), (64, 1))
        qd = jnp.ones((64, tree.nv), jnp.float32)
        f = jax.vmap(lambda q, qd: lg.bias_forces(tree, q, qd))
        assert "__ynn_fusion" not in jax.jit(f).lower(q, qd).compile().as_text()
    """, env={**os.environ, "XLA_FLAGS": YNN_OFF_FLAG})
