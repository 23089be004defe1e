"""How much faster do Brax's programs of a 3-D task run on a CPU with YNNPACK's fusions off (``XLA_FLAGS``)?

    python -m research.brax_ynn            # the ant and the humanoid, about a minute on 2 cores

Brax's trainers jit their own programs, which ``lg.compiler_options`` cannot reach; the same setting reaches them
as ``XLA_FLAGS=--xla_cpu_experimental_ynn_fusion_type=`` (``lagrange.compile.YNN_OFF_FLAG``), set before JAX starts.
Each measurement runs in a fresh interpreter, with and without the flag: 10 control steps of
:class:`lagrange.interop.brax.BraxEnv` over ``B`` environments (zero actions from the reset states), jitted as a
Brax trainer jits them (no compiler options), float32, the best of 3 calls after the first. Writes
``research/results/brax_ynn.json``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from optim.checkpoint import write_json
from research._cli import REPO

B, STEPS = 256, 10

CHILD = """
import json, sys, time
import jax, jax.numpy as jnp
from lagrange.interop.brax import BraxEnv
from lagrange.tasks import Ant, Humanoid
env = BraxEnv({"ant": Ant, "humanoid": Humanoid}[sys.argv[1]].diffrl())
B, T = int(sys.argv[2]), int(sys.argv[3])
s0 = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), B))

def roll(s):
    return jax.lax.scan(lambda s, _: (jax.vmap(env.step)(s, jnp.zeros((B, env.action_size))), None), s, None,
                        length=T)[0]

f = jax.jit(roll)
f(s0).obs.block_until_ready()
times = []
for _ in range(3):
    t = time.perf_counter()
    f(s0).obs.block_until_ready()
    times.append(time.perf_counter() - t)
print(json.dumps(min(times) / (B * T)))
"""


def measure(task: str, flag: bool) -> float:
    """Seconds per environment and control step in a fresh interpreter, with the flag or without it."""
    env = dict(os.environ)
    flags = env.get("XLA_FLAGS", "").replace("--xla_cpu_experimental_ynn_fusion_type=", "").strip()
    env["XLA_FLAGS"] = f"{flags} --xla_cpu_experimental_ynn_fusion_type=".strip() if flag else flags
    out = subprocess.run([sys.executable, "-c", CHILD, task, str(B), str(STEPS)], env=env, cwd=REPO,
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    rows = []
    for task in ("ant", "humanoid"):
        default, off = measure(task, False), measure(task, True)
        rows.append({"task": task, "B": B, "ms_per_env_step_default": 1e3 * default,
                     "ms_per_env_step_ynn_off": 1e3 * off, "speed_up": default / off})
        print(f"{task:9s} B = {B}: {1e3 * default:.3f} ms per env step with the default fusions, "
              f"{1e3 * off:.3f} with YNNPACK's off ({default / off:.1f}x)", flush=True)
    write_json(os.path.join(REPO, "research", "results", "brax_ynn.json"), {"steps": STEPS, "rows": rows}, indent=2)


if __name__ == "__main__":
    main()
