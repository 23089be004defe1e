"""Balanced swing-ups that exist: an open-loop swing-up found by CEM, caught by a saturated LQR, refined by Adam.

    python -m research.swingup_lqr                          # acrobot: swing-up times 1.9-2.2 s, 3 CEM seeds each
    python -m research.swingup_lqr --task double_cartpole   # swing-up times 0.4, 0.5 and 0.6 s
    python -m research.swingup_lqr --quick

What return can a controller really reach on the task's physics, swing-up *and* hold? ``swingup_bound`` scores
open-loop swing-ups by a perfect-hold estimate; this script builds whole controllers and runs them for the task's
full episode. The controller for a swing-up time ``T`` and offsets ``z`` (one per control step) is

    a_t = tanh(z_t)                                   for t < T   (open-loop swing-up)
    a_t = tanh(z_t + atanh(clip(-K dx_t, -1, 1)))     for t >= T  (the saturated LQR of research.upright_basin,
                                                                   plus a learnt offset; z = 0 is the LQR itself)

where ``dx`` is the state's deviation from upright at rest. First the cross-entropy method searches the swing-up
(``z`` for t < T, linearly interpolated between ``--knots`` values; ``z = 0`` after ``T``) for the return of the whole
episode from the noise-free hanging start; then Adam refines every ``z_t`` of the episode from the best found (the
best seen is kept). Reported per ``T`` and CEM seed: the return (true, over the task's horizon), whether it is
``balanced``, and the same controller, open loop as it is, from the 16 noisy starts of the paper tables (how robust
the swing-up is to the +-0.01 reset noise; a policy would add feedback). Each controller is re-run in float64 too:
the best is the highest return balanced in both precisions. The best controller's offsets are saved so
it can be rerun (``make_controller``), with the actions it applies (for plotting: replayed open loop they part from
the episode once round-off grows, since the upright chain is unstable without the feedback). This finds balanced
swing-ups and their returns, a lower bound on what the physics allows; it is not an upper bound. Writes
``research/results/swingup_lqr_<task>.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks._cli import add_bodies_flag, bodies_marker, bodies_suffix, marked_bodies, paper_task
from lagrange.control import upright_deviation, upright_state
from lagrange.tasks import TaskState, balanced
from optim.checkpoint import write_json
from research._ascent import adam_best_seen
from research._cli import at_least
from research.refine_swingup import arrival
from research.upright_basin import upright_lqr

RESULTS = pathlib.Path(__file__).resolve().parent / "results"
EVAL_EPISODES = 16  # the paper tables' noisy starts
DEFAULTS = {  # task: (swing-up times T, knots, Adam's learning rate for the refinement); --quick uses the middle T
    "acrobot": ((190, 200, 210, 220), 16, 1e-3),
    "double_cartpole": ((40, 50, 60), 12, 1e-2),
    "cartpole": ((30, 40, 50, 60), 8, 1e-2),
}
EDGE = 1.0 - 1e-6  # |LQR command| is clipped below 1 so that atanh stays finite


def make_controller(task, K, T: int):
    """``episode(z, s0) -> (return, states, actions (H,), rewards (H,))`` of the swing-up-then-LQR controller with
    offsets ``z`` (H,) from the state ``s0``; ``states`` is the visited :class:`TaskState`, ``s0`` included (H+1, n)."""
    K = jnp.asarray(K, jnp.asarray(upright_state(task)).dtype)
    deviation = upright_deviation(task)

    def lqr(s):
        return jnp.clip(-(K @ deviation(s.q, s.qd)), -EDGE, EDGE)

    def episode(z, s0):
        def body(s, x):
            t, zt = x
            a = jnp.tanh(zt + jnp.where(t < T, 0.0, jnp.arctanh(lqr(s))))
            s2 = task.step(s, a)
            return s2, (task.reward(s, a, s2), s2, a[0])

        _, (r, visited, a) = jax.lax.scan(body, s0, (jnp.arange(task.horizon), z[:, None]))
        states = jax.tree_util.tree_map(lambda x0, xs: jnp.concatenate([x0[None], xs]), s0, visited)
        return r.sum(), states, a, r

    return episode


def results_path(task_name: str, out: str | None = None, bodies: str = "rods") -> str:
    """``out``, or the default result file of ``task_name``: ``research/results/swingup_lqr_<task>.json``
    (``..._<task>_<bodies>.json`` for bodies other than the rods)."""
    return out or str(RESULTS / f"swingup_lqr_{task_name}{bodies_suffix(bodies)}.json")


def replay(task, K, row: dict):
    """The noise-free episode from hanging of a saved controller (``row``: a result's ``best``, with ``T`` and
    ``offsets``; ``K`` the result's ``lqr_gain``): ``(return, states, actions, rewards)`` as :func:`make_controller`."""
    s0 = hanging(task)
    episode = jax.jit(make_controller(task, np.asarray(K), row["T"]))
    return episode(jnp.asarray(row["offsets"], s0.q.dtype), s0)


def hanging(task) -> TaskState:
    """The noise-free hanging start, at rest, in the task's float type."""
    zeros = jnp.zeros(task.chain.n, jnp.result_type(task.chain.mass))
    return TaskState(zeros, zeros)


def arrival_penalties(task, q, rewards) -> dict:
    """When the episode arrives (``refine_swingup.arrival``: the first step from which every link stays within
    0.2 rad of upright) and the penalty ``10 x steps - return`` spent before and after it (None: never arrives); 10 is
    the most a step of the acrobot or double cartpole earns (the cartpole's reward, -th^2, has no such offset)."""
    arrive = arrival(task, np.asarray(q)[None])[0]
    rewards = np.asarray(rewards, np.float64)
    if arrive is None:
        return {"arrival_step": None, "penalty_before_arrival": None, "penalty_after_arrival": None}
    return {"arrival_step": arrive, "penalty_before_arrival": float(10 * arrive - rewards[:arrive].sum()),
            "penalty_after_arrival": float(10 * (rewards.size - arrive) - rewards[arrive:].sum())}


def knots_to_offsets(c, T: int, horizon: int):
    """Offsets (horizon,): ``c`` (knots,) interpolated linearly over the first ``T`` steps, zero after."""
    swing = jnp.interp(jnp.arange(T), jnp.linspace(0, T - 1, c.shape[-1]), c)
    return jnp.concatenate([swing, jnp.zeros(horizon - T, swing.dtype)])


def cem(score, knots: int, key, *, population: int, elites: int, iterations: int, init_std: float, dtype):
    """Cross-entropy method on ``score(c) -> return`` over ``c`` (knots,); ``(best c, best return)`` seen."""
    mean, std = jnp.zeros(knots, dtype), jnp.full(knots, init_std, dtype)
    best_c, best = mean, -np.inf
    scores = jax.jit(jax.vmap(score))
    for i in range(iterations):
        c = mean + std * jax.random.normal(jax.random.fold_in(key, i), (population, knots), dtype)
        r = scores(c)
        r = jnp.where(jnp.isfinite(r), r, -jnp.inf)
        top = jnp.argsort(-r)[:elites]
        if float(r[top[0]]) > best:
            best_c, best = c[top[0]], float(r[top[0]])
        mean, std = c[top].mean(0), c[top].std(0) + 0.02  # a floor keeps the search alive
    return best_c, best


def refine(episode, z, s0, *, steps: int, learning_rate: float):
    """Adam (cosine-decayed to 1 %) on every offset for the episode's return; ``(best z, best return)`` seen."""
    z, best, _ = jax.jit(lambda z: adam_best_seen(lambda z: episode(z, s0)[0], z, steps=steps,
                                                  learning_rate=learning_rate))(z)
    return z, float(best)


def rerun_float64(task, K, T: int, z) -> tuple[float, bool]:
    """The controller's noise-free episode re-run in float64: ``(return, balanced)``. A swing-up that arrives at the
    edge of the LQR's basin can depend on round-off; one that holds in both precisions does not."""
    with jax.enable_x64(True):
        task = paper_task(task.name, task.bodies)  # rebuilt inside the context: float64 parameters
        episode = make_controller(task, K, T)
        ret, states, _, _ = jax.jit(episode)(jnp.asarray(z, jnp.float64), hanging(task))
        return float(ret), bool(balanced(task, states.q))


def one(task, K, T: int, seed: int, *, knots: int, population: int, elites: int, iterations: int,
        refine_steps: int, learning_rate: float) -> dict:
    t0 = time.perf_counter()
    dtype = jnp.result_type(task.chain.mass)
    episode = make_controller(task, K, T)
    s0 = hanging(task)
    c, cem_return = cem(lambda c: episode(knots_to_offsets(c, T, task.horizon), s0)[0], knots,
                        jax.random.PRNGKey(seed), population=population, elites=elites, iterations=iterations,
                        init_std=3.0, dtype=dtype)
    z, seen = refine(episode, knots_to_offsets(c, T, task.horizon), s0, steps=refine_steps, learning_rate=learning_rate)
    ret, states, actions, rewards = jax.jit(episode)(z, s0)
    q = states.q
    ret64, balanced64 = rerun_float64(task, K, T, z)
    starts = jax.vmap(task.reset)(jax.random.split(jax.random.PRNGKey(10_000), EVAL_EPISODES))
    noisy_ret, noisy, _, _ = jax.jit(jax.vmap(lambda s: episode(z, s)))(starts)
    return {
        "T": T, "swing_up_seconds": T * task.dt, "seed": seed, "cem_return": cem_return,
        "refinement_best_seen": seen, "return": float(ret), "balanced": bool(balanced(task, q)),
        "return_float64": ret64, "balanced_float64": balanced64, "noisy_starts_mean_return": float(jnp.mean(noisy_ret)),
        "noisy_starts_balanced": int(jnp.sum(balanced(task, noisy.q))), **arrival_penalties(task, q, rewards),
        "seconds": time.perf_counter() - t0,
        "offsets": np.asarray(z, np.float64).tolist(), "actions": np.asarray(actions, np.float64).tolist(),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", choices=sorted(DEFAULTS), default="acrobot")
    add_bodies_flag(p)
    p.add_argument("--times", type=int, nargs="+", default=None, help="swing-up times T in control steps")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="CEM seeds per T")
    p.add_argument("--knots", type=int, default=None)
    p.add_argument("--population", type=int, default=2048)
    p.add_argument("--elites", type=int, default=64)
    p.add_argument("--iterations", type=int, default=150, help="CEM iterations")
    p.add_argument("--refine-steps", type=int, default=4000)
    p.add_argument("--lr", type=float, default=None, help="Adam's initial step in the refinement")
    p.add_argument("--r", type=float, default=1.0, help="LQR control weight R (Q as in research.upright_basin)")
    p.add_argument("--quick", action="store_true", help="the middle T, one seed, 30 CEM iterations, 500 Adam steps")
    p.add_argument("--out", default=None, help="result file (default research/results/swingup_lqr_<task>.json)")
    p.add_argument("--plot", default=None, help="also draw the best controller's episode to this PNG")
    p.add_argument("--replot", action="store_true",
                   help="only draw (--plot) the best controller of an existing result file (--out), no search")
    args = p.parse_args(argv)
    if args.replot:
        return replot(args)
    times, knots, lr = DEFAULTS[args.task]
    times = args.times or ([times[len(times) // 2]] if args.quick else list(times))
    seeds = args.seeds[:1] if args.quick else args.seeds
    iterations, refine_steps = (30, 500) if args.quick else (args.iterations, args.refine_steps)
    knots, lr = args.knots or knots, args.lr or lr
    task = paper_task(args.task, args.bodies)
    at_least(knots=(knots, 2), population=(args.population, 2), elites=(args.elites, 1),
             iterations=(iterations, 1), refine_steps=(refine_steps, 0), times=(min(times), 1))
    if args.elites > args.population:
        raise SystemExit(f"--elites ({args.elites}) must be <= --population ({args.population})")
    if max(times) > task.horizon:
        raise SystemExit(f"--times must be <= the task's horizon {task.horizon}, got {max(times)}")
    if not (lr > 0 and args.r > 0):
        raise SystemExit(f"--lr and --r must be > 0, got {lr} and {args.r}")
    K = upright_lqr(task, args.r)
    rows = []
    for T in times:
        for seed in seeds:
            r = one(task, K, T, seed, knots=knots, population=args.population, elites=args.elites,
                    iterations=iterations, refine_steps=refine_steps, learning_rate=lr)
            rows.append(r)
            print(f"T = {T} ({T * task.dt:.2f} s), seed {seed}: CEM {r['cem_return']:.1f} -> refined "
                  f"{r['return']:.1f} ({'balanced' if r['balanced'] else 'not balanced'}; "
                  f"float64 {r['return_float64']:.1f}, "
                  f"{'balanced' if r['balanced_float64'] else 'not balanced'}); from the 16 noisy starts "
                  f"{r['noisy_starts_mean_return']:.0f}, {r['noisy_starts_balanced']} balanced; {r['seconds']:.0f} s",
                  flush=True)
    held = [r for r in rows if r["balanced"] and r["balanced_float64"]]
    best = max(held, key=lambda r: r["return"]) if held else None
    out = {"task": args.task, **bodies_marker(args.bodies), "horizon": task.horizon,
           "knots": knots, "population": args.population, "elites": args.elites, "iterations": iterations,
           "refine_steps": refine_steps, "learning_rate": lr,
           "lqr_r": args.r, "lqr_gain": np.asarray(K).tolist(),
           "best_balanced_return": best["return"] if best else None,
           "best": best, "rows": [{k: v for k, v in r.items() if k not in ("offsets", "actions")} for r in rows]}
    path = results_path(args.task, args.out, args.bodies)
    write_json(path, out)
    if args.plot and best:
        plot(task, K, best, args.plot)
        print(f"drew {args.plot}")
    print(f"best balanced return {out['best_balanced_return']}; wrote {path}")
    return out


def replot(args) -> dict:
    """``--replot``: draw the best controller saved in a result file, with the gain saved beside it."""
    if not args.plot:
        raise SystemExit("--replot needs --plot PATH")
    path = results_path(args.task, args.out, args.bodies)
    with open(path) as f:
        out = json.load(f)
    if out.get("task") != args.task or marked_bodies(out) != args.bodies or not out.get("best"):
        raise SystemExit(f"{path} holds no balanced controller for --task {args.task} --bodies {args.bodies}")
    plot(paper_task(args.task, args.bodies), np.asarray(out["lqr_gain"]), out["best"], args.plot)
    print(f"drew {args.plot} from {path}")
    return out


def plot(task, K, row: dict, path: str) -> None:
    """Angles (the cart on its own axis), velocities and the actuator's force or torque over the best controller's
    noise-free episode, with the step where LQR takes over marked."""
    from lagrange.plotting import episode_figure

    ret, states, actions, _ = replay(task, K, row)
    title = f"{task.name}: open-loop swing-up ({row['T'] * task.dt:.2f} s) + LQR, return {float(ret):.0f}"
    episode_figure(task, states.q, actions, path, qd=states.qd, title=title,
                   marks=[(row["T"] * task.dt, "LQR takes over")])


if __name__ == "__main__":
    main()
