"""The XLA flag lagrange sets on import, before JAX starts a backend: ``--xla_cpu_experimental_ynn_fusion_type=``.

jaxlib 0.10's CPU compiler hands reductions and the elementwise work around them to YNNPACK ("ynn fusions"). On the
small batched 3x3 and 6x6 products of these dynamics (sums over axes of length 3 and 6) that runs several times
slower than XLA's own loops: Gymnasium's ant on the ground, its bias forces at B = 1024 in float32, 17.0 µs an
environment with them and 2.1 µs without; a 16-substep control step at B = 64, 23.1 ms against 4.0 ms in float32 and
11.5 ms against 5.1 ms in float64 (the upstream report: jax-ml/jax#37465, openxla/xla#46351). The empty value turns
the ynn fusions off and leaves every other fusion to XLA, which computes the same operations in another order (results
agree to round-off).

A user who sets ``--xla_cpu_experimental_ynn_fusion_type`` in ``XLA_FLAGS`` keeps their value. The flag acts only on
programs compiled after JAX reads it, when its first backend starts: import lagrange before running JAX computations
(as ``import lagrange`` at the top of a script does).
"""

import os

FLAG = "--xla_cpu_experimental_ynn_fusion_type"


def apply(environ=os.environ) -> bool:
    """Add ``FLAG=`` (empty: no ynn fusions) to ``environ["XLA_FLAGS"]`` unless the user set the flag.

    Args:
        environ: the environment to change.

    Returns:
        Whether it was added.
    """
    flags = environ.get("XLA_FLAGS", "")
    if FLAG in flags:
        return False
    environ["XLA_FLAGS"] = f"{flags} {FLAG}=".strip()
    return True


apply()
