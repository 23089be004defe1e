"""``compiler_options(model)``: the XLA options a jitted program of a spatial tree runs best with on a CPU.

jaxlib 0.10's CPU compiler hands reductions and the elementwise work around them to YNNPACK ("ynn fusions"). On the
small batched 3x3 and 6x6 products of a spatial tree's dynamics (sums over axes of length 3 and 6) that runs several
times slower than XLA's own loops: Gymnasium's ant on the ground, its bias forces at B = 1024 in float32, 17.0 µs an
environment with them and 2.1 µs without; a 16-substep control step at B = 64, 23.1 ms against 4.0 ms in float32 and
11.5 ms against 5.1 ms in float64 (the upstream report: jax-ml/jax#37465, openxla/xla#46351). Writing the sums out
as adds avoids the ynn fusions but runs 2x slower than XLA's loops; the option below keeps XLA's loops.

The planar chains and trees gain nothing measurable from it (their programs hold no such reductions), and a policy's
matrix products keep YNNPACK's kernels there: any change of fusion moves round-off, which a chaotic swing-up amplifies
(the CE-APG acrobot's ``--quick`` run ends at 2534 with the default fusions and at 1298 with YNNPACK's reductions off),
so they are compiled as before.

    step = jax.jit(jax.vmap(f), compiler_options=lg.compiler_options(tree))

The library's own jitted programs of a task (``optim``'s trainers and evaluations) pass it.
"""

from __future__ import annotations


__all__ = ["YNN_OFF_FLAG", "compiler_options"]

YNN_OFF = {"xla_cpu_experimental_ynn_fusion_type": ""}
"""No ynn fusion: every fusion left to XLA."""

YNN_OFF_FLAG = "--xla_cpu_experimental_ynn_fusion_type="
""":data:`YNN_OFF` as an ``XLA_FLAGS`` entry, for programs that others jit (Brax's trainers), which
``compiler_options`` cannot reach. It must be in the environment before JAX starts, and then holds for every program
of the process: ``XLA_FLAGS=--xla_cpu_experimental_ynn_fusion_type= python train.py``. Brax's PPO on DFlex's humanoid
through :class:`~lagrange.interop.brax.BraxEnv` runs 8x faster with it on a CPU (its control step at B = 256:
0.30 ms an environment against 3.06 ms; the ant's 0.050 against 0.330: ``python -m research.brax_ynn``)."""


def compiler_options(model, backend: str | None = None, *, general: bool = False) -> dict[str, str] | None:
    """The ``compiler_options`` of ``jax.jit`` for programs of ``model``: :data:`YNN_OFF` for a tree whose dynamics
    are the general rigid-body algorithms' (:func:`lagrange.dynamics.backend`: a 3-D tree, or any tree with
    ``general=True``) compiled for a CPU, else None (the compiler's defaults: a planar tree's).

    Args:
        model: a :class:`lagrange.Tree` (a :class:`lagrange.Chain` is one), or anything else: None.
        backend: the platform the program is compiled for (default: JAX's default backend).
        general: the program runs the general algorithms even on a planar tree (``simulate(..., general=True)``).
    """
    from lagrange.dynamics import backend as prepared
    from lagrange.model.tree import Tree
    from lagrange.rbda.backend import General

    if not isinstance(model, Tree) or not isinstance(prepared(model, check=False, general=general), General):
        return None
    if backend is None:
        import jax

        backend = jax.default_backend()
    return dict(YNN_OFF) if backend == "cpu" else None
