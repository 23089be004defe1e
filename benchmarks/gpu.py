"""What an accelerator measures: the acrobot beside MJX and Brax, n-link pendulums, the legged models beside MJX, 3-D
trees beside MJX, SHAC's hopper epoch and Table I's PPO at the paper's budget, in one process on whatever device JAX
finds.

    python -m benchmarks.gpu                          # every section (sized for <= 8 minutes on one H100/H200)
    python -m benchmarks.gpu --sections acrobot legged trees3d
    python -m benchmarks.gpu --small                  # tiny sizes, one batch, the peers' forward only (a test runs it)

Throughput (sections ``acrobot``, ``scaling``, ``legged``): for each engine one environment's rollout
``(q0, qd0, us) -> (q_T, qd_T)`` under ``jax.vmap`` and ``jax.jit``; forward = the final state, gradient = reverse mode
of ``sum(q_T^2 + qd_T^2)`` with respect to the controls (acrobot) or the initial state (pendulums, legged models);
the median of ``REPEATS`` calls after the first, whose seconds are recorded too (compilation). Acrobot:
``lagrange.systems.acrobot()``, dt 0.01, ``T`` steps, float32 and float64, MJX and Brax generalized on the chain
``to_mjcf`` writes. Legged: Gymnasium's half-cheetah in free flight and hopper on the ground exactly as
``benchmarks/throughput.py --legged-only`` builds them, float32. ``trees3d``: spatial trees as
``benchmarks/trees3d.py`` builds them, float32, semi-implicit Euler: dm_control's humanoid in free flight (27 dof)
and Gymnasium's half-cheetah read as a 3-D ``Tree`` (the planar model without the planar path: no loop over its links,
where ``legged``'s planar chain runs three), beside MJX on the same MuJoCo models; Gymnasium's ant on the ground with
DFlex's laws at 1/960 s, beside MJX's own contact (``opt.iterations = 1``). ``shac``: epochs of
``SHACConfig.hopper()`` on ``Hopper.diffrl()`` (256 environments x 32 steps), seconds per epoch after the first.
``ppo``: Brax PPO with the CE-APG paper's appendix IX-C hyperparameters at its full budget (8e7 env steps) on
``DoubleCartpole.brax_v1()``, each final deterministic policy evaluated on the training benchmarks' 16 starts.

Needs nothing beyond the project, JAX, MuJoCo/MJX and Brax (no network). Writes
``benchmarks/results/gpu_<device>.json`` and ``.md`` (``--small``: ``runs/benchmarks/gpu_<device>_small.*``), after
every section, so that a run cut short keeps what it measured. Read: ``docs/benchmarks.md`` ("On a GPU").
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import os
import pathlib
import re
import subprocess
import time

import jax
import jax.numpy as jnp

import lagrange as lg
from benchmarks._cli import REPO, gymnasium_model, markdown_table, outputs
from benchmarks._engines import brax_rollout, mjx_rollout
from benchmarks._timing import median_time
from benchmarks.throughput import LEGGED, _jax_pair, _legged_inputs, legged_model
from benchmarks.throughput import _inputs as _inputs64  # float64 draws, cast per table
from lagrange.interop.mjcf import from_mjcf
from optim.checkpoint import write_json
from oracles import closed_form as cf

SECTIONS = ("acrobot", "scaling", "legged", "trees3d", "shac", "ppo")
REPEATS = 5
FULL = dict(
    acrobot_T=100, acrobot_batches=(1, 1024, 131_072, 1_048_576), acrobot_peer_batch=131_072,
    acrobot_f64_batches=(131_072, 1_048_576), scaling_batch=65_536, scaling_ns=(4, 16, 32), scaling_T=100,
    legged_batches=(4096, 65_536), legged_T=20, trees3d_batches=(4096, 65_536), trees3d_T=20, shac_epochs=40,
    ppo_seeds=(0, 1, 2), ppo_steps=80_000_000, ppo_evals=11,
)
SMALL = dict(
    acrobot_T=5, acrobot_batches=(8,), acrobot_peer_batch=8, acrobot_f64_batches=(8,), scaling_batch=8,
    scaling_ns=(4,), scaling_T=5, legged_batches=(8,), legged_T=2, trees3d_batches=(8,), trees3d_T=2, shac_epochs=2,
    ppo_seeds=(0,), ppo_steps=None, ppo_evals=2,
)
# the CE-APG paper's appendix IX-C PPO at its budget (benchmarks/algorithms.py's PPO_HP and batch geometry)
PPO_PAPER = dict(num_envs=512, batch_size=256, num_minibatches=32)
PPO_SMALL = dict(num_timesteps=2 * 8 * 5 * 4 * 2, num_envs=8, batch_size=8, num_minibatches=2)


def device_info() -> dict:
    """The device JAX computes on, the versions that matter and the project's commit."""
    d = jax.devices()[0]
    versions = {}
    for pkg in ("jax", "jaxlib", "diffrax", "equinox", "optax", "mujoco", "mujoco-mjx", "brax"):
        try:
            versions[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            versions[pkg] = None
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                                timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return dict(device=d.device_kind, platform=d.platform, device_count=jax.device_count(), versions=versions,
                commit=commit, cpu_count=os.cpu_count())


@contextlib.contextmanager
def precision(dtype):
    """JAX's 64-bit mode on for float64, off for float32 while the block builds and traces its engines (MJX and Brax
    take their dtype from it), restored after."""
    before = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", jnp.dtype(dtype) == jnp.float64)
    try:
        yield
    finally:
        jax.config.update("jax_enable_x64", before)


def _inputs(n, m, B, T, dtype):
    """``benchmarks/throughput.py``'s inputs ``(q0, qd0, us)`` in ``dtype``."""
    return lg.astype(_inputs64(n, m, B, T), dtype)


def _lagrange(chain, solver, dt, argnums, general=False):
    """The jitted forward and gradient of ``chain``'s rollout (the general algorithms' with their per-program compiler
    options: YNNPACK off on a CPU); ``general``: the general algorithms on a planar tree too."""
    def rollout(q0, qd0, us):
        tr = lg.simulate(chain, q0, qd0, us, dt, solver, check=False, general=general)
        return tr.q[-1], tr.qd[-1]

    return _jax_pair(rollout, argnums, compiler_options=lg.compiler_options(chain, general=general))


def _time(fn, args):
    """``(median seconds per call, seconds of the first call)``."""
    t = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t
    return median_time(fn, *args, repeats=REPEATS, min_time=0.0, warmup=0), first


def _rows(section, engine, pair, args, T, dtype, gradient=True, **extra):
    """The forward (and gradient) rows of one engine on ``args``."""
    out = []
    for kind, fn in zip(("forward", "gradient"), pair[: 2 if gradient else 1]):
        t, first = _time(fn, args)
        B = args[0].shape[0]
        out.append(dict(section=section, engine=engine, kind=kind, batch=B, steps=T, median_s=t, first_call_s=first,
                        env_steps_per_s=B * T / t, dtype=jnp.dtype(dtype).name, **extra))
        print(f"  {section} {engine} {kind} B={B} {out[-1]['dtype']}: {out[-1]['env_steps_per_s']:.3g} env-steps/s "
              f"(first call {first:.1f} s)", flush=True)
    return out


def acrobot_rows(s):
    T, dt, rows = s["acrobot_T"], 0.01, []
    for dtype, batches in ((jnp.float32, s["acrobot_batches"]), (jnp.float64, s["acrobot_f64_batches"])):
        with precision(dtype):
            rows += _acrobot_rows(s, dtype, batches, T, dt)
    return rows


def _acrobot_rows(s, dtype, batches, T, dt):
    rows, chain = [], lg.systems.acrobot()
    engines = {"lagrange_sie": _lagrange(chain, lg.SemiImplicitEuler(), dt, 2)}
    if dtype == jnp.float32:
        engines["lagrange_rk4"] = _lagrange(chain, lg.RK4(), dt, 2)
    for B in batches:
        args = _inputs(2, 1, B, T, dtype)
        for name, pair in engines.items():
            rows += _rows("acrobot", name, pair, args, T, dtype)
    if dtype == jnp.float64 and s is not FULL:
        return rows
    args = _inputs(2, 1, s["acrobot_peer_batch"], T, dtype)
    params = cf.acrobot.Params()
    peers = {"mjx_euler": _jax_pair(mjx_rollout(chain, dt))}
    if dtype == jnp.float32:
        peers["closed_form_rk4"] = _jax_pair(
            lambda q0, qd0, us: tuple(x[-1] for x in cf.rollout(cf.acrobot.forward_dynamics, params, q0, qd0, us,
                                                                dt)))
        peers["brax_generalized_sie"] = _jax_pair(brax_rollout(chain, dt))
    for name, pair in peers.items():  # --small: the peers' forward only (their gradients compile for minutes on a CPU)
        rows += _rows("acrobot", name, pair, args, T, dtype, gradient=s is FULL or name == "closed_form_rk4")
    return rows


def scaling_rows(s):
    rows, T, dt = [], s["scaling_T"], 0.01
    for n in s["scaling_ns"]:
        chain = lg.astype(lg.systems.n_link_pendulum(n), jnp.float32)
        args = _inputs(n, chain.m, s["scaling_batch"], T, jnp.float32)
        rows += _rows("scaling", "lagrange_sie", _lagrange(chain, lg.SemiImplicitEuler(), dt, (0, 1)), args, T,
                      jnp.float32, n=n)
    return rows


def legged_rows(s):
    rows, T = [], s["legged_T"]
    for name, (xml, limits, contact, constraints, _) in LEGGED.items():
        chain = from_mjcf(gymnasium_model(xml), limits=limits, contact=contact)
        model = legged_model(xml, constraints)
        mjx_model = legged_model(xml, constraints, iterations=1)
        dt = model.opt.timestep
        engines = {"lagrange_sie": _lagrange(lg.astype(chain, jnp.float32), lg.SemiImplicitEuler(), dt, (0, 1))}
        if s is FULL or not constraints:  # --small: MJX in free flight only (its contact solver compiles for long)
            engines["mjx"] = _jax_pair(mjx_rollout(mjx_model, dt), (0, 1))
        for B in s["legged_batches"]:
            (q0, qd0, us), touching = _legged_inputs(chain, model, B)
            args = lg.astype((q0, qd0, us[:, :T]), jnp.float32)
            for e, pair in engines.items():  # MJX's gradient through its contact solver: not run (memory)
                # --small: lagrange's gradient in free flight only (the hopper's on the ground compiles for long)
                gradient = (s is FULL or not constraints) if e == "lagrange_sie" else (s is FULL and not constraints)
                rows += _rows("legged", e, pair, args, T, jnp.float32, gradient=gradient, model=name,
                              states_touching_in_mujoco=touching)
    return rows


def trees3d_rows(s):
    import numpy as np

    x64 = jax.config.jax_enable_x64
    from benchmarks import trees3d  # its first import turns 64-bit mode on

    jax.config.update("jax_enable_x64", x64)

    rows, T = [], s["trees3d_T"]
    rng = np.random.default_rng(0)
    free = {"humanoid_free_flight": trees3d.MODELS["dm_control humanoid"](),
            "half_cheetah_tree": gymnasium_model("half_cheetah")}
    for name, path in free.items():
        model, tree = trees3d.free_flight(path)
        engines = {"lagrange_sie": _lagrange(lg.astype(tree, jnp.float32), lg.SemiImplicitEuler(),
                                             model.opt.timestep, (0, 1), general=True)}
        if s is FULL:  # --small: lagrange only (MJX's 3-D compiles are long on a CPU; the other sections run MJX)
            engines["mjx"] = _jax_pair(mjx_rollout(model, model.opt.timestep), (0, 1))
        for B in s["trees3d_batches"]:
            q0, qd0 = trees3d.states(model, rng, B)
            args = lg.astype(tuple(jnp.asarray(x) for x in (q0, qd0, rng.uniform(-1, 1, (B, T, model.nu)))),
                             jnp.float32)
            for e, pair in engines.items():
                rows += _rows("trees3d", e, pair, args, T, jnp.float32, model=name,
                              gradient=s is FULL or name == "half_cheetah_tree")
    for B in s["trees3d_batches"]:
        model, tree, inputs = trees3d._ant_on_the_ground(B, T)
        engines = {"lagrange_sie": _lagrange(lg.astype(tree, jnp.float32), lg.SemiImplicitEuler(),
                                             trees3d.DFLEX_ANT["dt"], (0, 1))}
        if s is FULL:
            model.opt.iterations = 1  # more: MJX's while_loop cannot be reverse-differentiated (mujoco#2259)
            engines["mjx"] = _jax_pair(mjx_rollout(model, model.opt.timestep), (0, 1))
        args = lg.astype(tuple(jnp.asarray(x) for x in inputs), jnp.float32)
        for e, pair in engines.items():
            rows += _rows("trees3d", e, pair, args, T, jnp.float32, model="ant_on_the_ground", gradient=s is FULL)
    return rows


def shac_rows(s):
    from lagrange.tasks import Hopper
    from optim import SHACConfig
    from policies import Actor

    task = Hopper.diffrl()
    config = SHACConfig.hopper(**({} if s is FULL else dict(num_envs=8)))
    trainer = config.make_trainer(task, Actor.for_task(task))
    state = trainer.init(jax.random.PRNGKey(0))
    t = time.perf_counter()
    state, _ = trainer.update(state)
    jax.block_until_ready(state)
    first = time.perf_counter() - t
    t = time.perf_counter()
    for _ in range(s["shac_epochs"]):
        state, _ = trainer.update(state)
    jax.block_until_ready(state)
    per = (time.perf_counter() - t) / s["shac_epochs"]
    row = dict(section="shac", task="hopper", num_envs=config.num_envs, short_horizon=config.short_horizon,
               epochs=s["shac_epochs"], s_per_epoch=per, first_epoch_s=first,
               env_steps_per_s=config.env_steps_per_epoch() / per)
    print(f"  shac hopper: {per:.3g} s per epoch of {config.num_envs} x {config.short_horizon} (first {first:.1f} s)",
          flush=True)
    return [row]


def ppo_rows(s):
    from benchmarks.algorithms import PPO_HP, train_one

    budget = dict(PPO_HP, num_evals=s["ppo_evals"])
    budget |= PPO_SMALL if s["ppo_steps"] is None else dict(PPO_PAPER, num_timesteps=s["ppo_steps"])
    rows = []
    for seed in s["ppo_seeds"]:
        r = train_one("ppo", "double_cartpole", seed, budget, "paper" if s is FULL else "small", bodies="brax_v1")
        rows.append(dict(section="ppo", task="double_cartpole", bodies="brax_v1", seed=seed, env_steps=r["env_steps"],
                         **{k: r[k] for k in ("return", "returns", "balanced_fraction", "wall_clock", "curve")}))
        print(f"  ppo double cartpole seed {seed}: return {r['return']} ({r['balanced_fraction']:.0%} balanced) in "
              f"{r['wall_clock']:.0f} s", flush=True)
    return rows


RUN = {"acrobot": acrobot_rows, "scaling": scaling_rows, "legged": legged_rows, "trees3d": trees3d_rows,
       "shac": shac_rows, "ppo": ppo_rows}
COLUMNS = {
    "acrobot": ["engine", "kind", "batch", "dtype", "env_steps_per_s", "first_call_s"],
    "scaling": ["n", "kind", "batch", "env_steps_per_s", "first_call_s"],
    "legged": ["model", "engine", "kind", "batch", "env_steps_per_s", "first_call_s"],
    "trees3d": ["model", "engine", "kind", "batch", "env_steps_per_s", "first_call_s"],
    "shac": ["task", "num_envs", "short_horizon", "epochs", "s_per_epoch", "first_epoch_s"],
    "ppo": ["task", "seed", "env_steps", "return", "balanced_fraction", "wall_clock"],
}


def write(out, path):
    """``out`` as ``path`` (JSON) and the same name with ``.md`` (a table per section)."""
    write_json(path, out)
    info = out["info"]
    lines = [f"# {info['device']} ({info['platform']}), jax {info['versions']['jax']}, commit {info['commit']}", "",
             f"`python -m benchmarks.gpu{' --small' if out['small'] else ''}`; seconds per section: "
             + ", ".join(f"{k} {v:.0f}" for k, v in out["section_s"].items()), ""]
    for section in out["section_s"]:
        rows = [r for r in out["rows"] if r["section"] == section]
        if rows:
            lines += [f"## {section}", "", markdown_table(rows, COLUMNS[section]), ""]
    path.with_suffix(".md").write_text("\n".join(lines))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    ap.add_argument("--small", action="store_true", help="tiny sizes (any device; a test runs it on the CPU)")
    ap.add_argument("--out", default=None, help="the JSON file to write (default: by device, see above)")
    args = ap.parse_args(argv)
    sizes = SMALL if args.small else FULL
    info = device_info()
    name = re.sub(r"[^a-z0-9]+", "_", info["device"].lower()).strip("_") + ("_small" if args.small else "")
    path = outputs(args.small)[0] / f"gpu_{name}.json" if args.out is None else pathlib.Path(args.out)
    out = dict(info=info, small=args.small, sizes=sizes, section_s={}, rows=[])
    print(f"{info['device']} ({info['platform']}), jax {info['versions']['jax']}; writing {path}", flush=True)
    for section in args.sections:
        t = time.perf_counter()
        with precision(jnp.float32):  # the training sections in float32, as they train
            out["rows"] += RUN[section](sizes)
        out["section_s"][section] = time.perf_counter() - t
        write(out, path)
    print(f"wrote {path} and {path.with_suffix('.md')} in {sum(out['section_s'].values()):.0f} s")
    return out


if __name__ == "__main__":
    main()
