"""What a SHAC run on the SNU humanoid holds so far: read a copy of its checkpoint while it trains (or after it was
stopped), and write the figures and the numbers the example writes at its end, for the epoch reached.

The default run (``examples/snu_humanoid_shac.py``, 2000 epochs) takes longer on these 2 cores than one working
session; this reads its state part way, without disturbing it (the checkpoint is copied first, then verified by its
digest as ``optim.load`` reads it).

    python -m research.snu_snapshot runs/locomotion/shac_snu_humanoid_0 --out research/results/snu_snapshot

Writes ``snapshot.json`` (the epoch, its training wall-clock, the learning curve's evaluations, the deterministic
policy's return over 16 random starts, one episode's distance), ``learning_curve.png``, ``gait.png`` and ``gait.gif``.
"""

import argparse
import json
import os
import shutil
import tempfile

import jax
import numpy as np

from lagrange.compile import compiler_options
from lagrange.tasks import SNUHumanoid
from optim import load
from optim.cli import EVAL_EPISODES
from optim.episode import episode, evaluate
from optim.locomotion_cli import episode_figures
from policies import Actor


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", help="the run's folder (holding checkpoint.eqx)")
    p.add_argument("--out", default="research/results/snu_snapshot")
    p.add_argument("--seed", type=int, default=0, help="the run's seed (the evaluation starts: PRNGKey(10000 + seed))")
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    task = SNUHumanoid.diffrl()
    with tempfile.TemporaryDirectory() as tmp:
        path = shutil.copy(os.path.join(args.run, "checkpoint.eqx"), os.path.join(tmp, "checkpoint.eqx"))
        trainer, state, head = load(path, task, Actor.for_task(task, units=(512, 256)))
    policy, norm = trainer.policy(state)
    history, curve = head["history"], head["curve"]
    key = jax.random.PRNGKey(10_000 + args.seed)
    returns, ok = jax.jit(lambda k: evaluate(task, policy, norm, k, EVAL_EPISODES),
                          compiler_options=compiler_options(task.chain))(key)
    ep = jax.jit(lambda k: episode(task, policy, norm, k), compiler_options=compiler_options(task.chain))(key)
    out = {
        "epoch": int(head["iteration"]), "training_s": history[-1]["elapsed"], "env_steps": history[-1]["env_steps"],
        "return": float(np.mean(returns)), "return_std": float(np.std(returns)), "stayed_up": float(np.mean(ok)),
        "example_episode_return": float(ep.ret), "example_episode_distance_m": float(ep.q[-1, 0] - ep.q[0, 0]),
        "curve": [{k: c[k] for k in ("iteration", "env_steps", "elapsed", "return", "return_std")} for c in curve],
    }
    with open(os.path.join(args.out, "snapshot.json"), "w") as f:
        json.dump(out, f, indent=1)
    episode_figures(task, ep, args.out, history=history, curve=curve, anchor=4246.0,
                    title=f"SHAC on snu_humanoid (seed {args.seed}, epoch {out['epoch']})")
    print(json.dumps({k: v for k, v in out.items() if k != "curve"}))
    return out


if __name__ == "__main__":
    main()
