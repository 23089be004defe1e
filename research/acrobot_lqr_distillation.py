"""CE-APG on the acrobot with an LQR distillation term near upright in every candidate's APG loss.

    python -m research.acrobot_lqr_distillation --seed 0 --bc --upright 0   # from the BC policy
    python -m research.acrobot_lqr_distillation --seed 0 --upright 0.25     # from zeros
    (about 15 minutes each with two at a time on two cores; research/LOG.md's runs: seeds 0 and 1 of each, and
    with --lam 0 --bc --bc-norm lqr seeds 0-3)

Each candidate's APG loss is ``-mean return + lam * mean_episodes sum_t w_t ||a_t - a*_t||^2`` with ``a*_t`` the
saturated LQR's action (``research.upright_basin``'s gain, r = 1) and ``w_t = exp(-(th1^2 + th2^2) / (2 sigma^2))``
(wrapped angles, 0 = upright); the fitness that selects the elites stays the return. The loss is the ``objective``
of ``CEAPGConfig.make_trainer`` with the distillation term in the gradient only (``research._apg.gradient_only``, so
the returns the fitness averages stay the batch returns), the rest the laptop protocol.

``--bc`` starts the CE mean at a GRU behaviour-cloned from the LQR: 512 LQR episodes of 300 steps from upright +-0.02,
Adam 3e-3 cosine-decayed over 4000 steps of 32 sequences, action MSE; the normaliser is fitted to those observations
and to 512 hanging episodes (their first 300 steps) under random piecewise-constant torque (``--bc-norm lqr``: to the
LQR's observations only), then given a count of 4000 so that training moves it; both are put in place of the CE mean
and normaliser in the state ``trainer.init`` returns. ``--lam 0`` is plain CE-APG (the library's loss); with ``--bc``
it starts from the cloned policy. Prints the BC policy's upright evaluation, then every 10 iterations the best
candidate's training return and its return and balanced count over the 16 evaluation episodes (key 1234), and over 16
upright starts (key 5, as the BC policy's).
"""

import argparse
import dataclasses
import time

import jax
import jax.numpy as jnp
import optax

from benchmarks._cli import paper_task
from lagrange import tasks
from lagrange.control import saturated_lqr, upright_state
from lagrange.tasks import wrap
from optim import CEAPGConfig, evaluate, flatten_policy
from policies import GRUPolicy, Normalizer
from research._apg import WIDTH, gradient_only, laptop_policy, laptop_task
from research.upright_basin import upright_lqr


def make_teacher(task):
    """``teacher(q, qd) -> a*`` (..., 1), the saturated LQR, and the upright coordinates."""
    return saturated_lqr(task, upright_lqr(task, 1.0)), jnp.asarray(upright_state(task))[:task.chain.n]


def distillation_objective(teacher, upright_q, lam, sigma):
    """The APG objective with the distillation term added (the reported return, which the fitness averages, stays
    the batch return)."""

    def term(eps):
        q, qd = eps.q[:, :-1], eps.qd[:, :-1]
        w = jnp.exp(-jnp.sum(wrap(q - upright_q) ** 2, -1) / (2 * sigma**2))
        gap = jnp.sum((eps.actions - jax.lax.stop_gradient(teacher(q, qd))) ** 2, -1)
        return lam * jnp.mean(jnp.sum(w * gap, -1))

    return gradient_only(term)


def behaviour_clone(task, teacher, seed, swing_norm=True):
    """``(flat parameters, normaliser)`` of a GRU cloned from the LQR (see the module docstring)."""

    def lqr_episode(k):
        def body(s, _):
            a = teacher(s.q, s.qd)
            return task.step(s, a), (task.observe(s), a)

        return jax.lax.scan(body, dataclasses.replace(task, upright=1.0, noise=0.02).reset(k), None, length=300)[1]

    def torque_episode(k):
        torques = jnp.repeat(jax.random.uniform(k, (25, 1), minval=-1, maxval=1), 20, axis=0)
        return jax.lax.scan(lambda s, a: (task.step(s, a), task.observe(s)), task.reset(k), torques)[1][:300]

    obs, acts = jax.jit(jax.vmap(lqr_episode))(jax.random.split(jax.random.PRNGKey(77), 512))
    swing = jax.jit(jax.vmap(torque_episode))(jax.random.split(jax.random.PRNGKey(78), 512))
    size = obs.shape[-1]
    fit = [obs.reshape(-1, size), swing.reshape(-1, size)] if swing_norm else [obs.reshape(-1, size)]
    norm = Normalizer.create(size).update(jnp.concatenate(fit))
    norm = dataclasses.replace(norm, count=jnp.asarray(4000.0, norm.count.dtype))
    flat, unravel = flatten_policy(GRUPolicy.for_task(task, WIDTH["acrobot"], key=jax.random.PRNGKey(seed)))
    adam = optax.adam(optax.cosine_decay_schedule(3e-3, 4000))

    def bc_loss(p, idx):
        policy = unravel(p)

        def actions(o):
            def body(h, x):
                t, ob = x
                a, h = policy(norm(ob), h, t == 0)
                return h, a

            return jax.lax.scan(body, policy.initial_state(), (jnp.arange(o.shape[0]), o))[1]

        return jnp.mean((jax.vmap(actions)(obs[idx]) - acts[idx]) ** 2)

    @jax.jit
    def bc_step(p, opt, k):
        loss, g = jax.value_and_grad(bc_loss)(p, jax.random.choice(k, 512, (32,), replace=False))
        upd, opt = adam.update(g, opt, p)
        return optax.apply_updates(p, upd), opt, loss

    opt = adam.init(flat)
    for i in range(4000):
        flat, opt, loss = bc_step(flat, opt, jax.random.PRNGKey(1000 + i))
        if i % 1000 == 0 or i == 3999:
            print(f"behaviour cloning step {i}: action MSE {float(loss):.2e}", flush=True)
    upright = dataclasses.replace(task, upright=1.0)
    returns, balanced = jax.jit(lambda p: evaluate(upright, unravel(p), norm, jax.random.PRNGKey(5), 16))(flat)
    print(f"BC policy from upright: return {float(returns.mean()):.0f}, balanced {int(balanced.sum())} of 16",
          flush=True)

    def lqr_evaluation(k):  # the teacher itself on the same 16 upright starts, 500 steps
        def body(s, _):
            s2 = task.step(s, teacher(s.q, s.qd))
            return s2, (task.reward(s, None, s2), s2.q)

        s0 = upright.reset(k)
        _, (r, q) = jax.lax.scan(body, s0, None, length=upright.horizon)
        return jnp.sum(r), jnp.concatenate([s0.q[None], q])

    lqr_returns, lqr_q = jax.jit(jax.vmap(lqr_evaluation))(jax.random.split(jax.random.PRNGKey(5), 16))
    print(f"the LQR itself from upright: return {float(lqr_returns.mean()):.0f}, balanced "
          f"{int(tasks.balanced(upright, lqr_q).sum())} of 16", flush=True)
    return flat, norm


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--lam", type=float, default=10.0, help="weight of the distillation term (0: plain CE-APG)")
    p.add_argument("--sigma", type=float, default=0.2, help="width of the near-upright weight [rad]")
    p.add_argument("--upright", type=float, default=0.25, help="upright_starts of the training episodes")
    p.add_argument("--bodies", default="rods", choices=("rods", "brax_v1"))
    p.add_argument("--iterations", type=int, default=150)
    p.add_argument("--bc", action="store_true", help="start the CE mean at the behaviour-cloned LQR")
    p.add_argument("--bc-norm", choices=("lqr+swing", "lqr"), default="lqr+swing",
                   help="observations the BC normaliser is fitted to: the LQR's and the random-torque swings', or "
                        "the LQR's only")
    args = p.parse_args(argv)
    teacher, upright_q = make_teacher(paper_task("acrobot", args.bodies))
    objective = distillation_objective(teacher, upright_q, args.lam, args.sigma) if args.lam > 0 else None
    cfg = CEAPGConfig.laptop("acrobot", upright_starts=args.upright).with_iterations(args.iterations)
    task = laptop_task("acrobot", args.bodies)
    trainer = cfg.make_trainer(task, laptop_policy("acrobot", task), objective=objective)
    state = trainer.init(jax.random.PRNGKey(args.seed))
    if args.bc:
        flat, norm = behaviour_clone(trainer.task, teacher, args.seed, args.bc_norm == "lqr+swing")
        state = state._replace(mean=flat, best=flat, normalizer=norm, best_normalizer=norm)
    scores = jax.jit(lambda policy, norm: evaluate(trainer.task, policy, norm, jax.random.PRNGKey(1234), 16))
    upright = dataclasses.replace(trainer.task, upright=1.0)
    upright_scores = jax.jit(lambda policy, norm: evaluate(upright, policy, norm, jax.random.PRNGKey(5), 16))
    t0 = time.time()
    for it in range(cfg.iterations):
        state, metrics = trainer.update(state)
        if (it + 1) % 10 == 0 or it + 1 == cfg.iterations:
            returns, balanced = scores(*trainer.policy(state))
            up_returns, up_balanced = upright_scores(*trainer.policy(state))
            print(f"iteration {it + 1}: best training return {float(metrics['best_return']):.0f}, evaluation "
                  f"{float(jnp.mean(returns)):.0f}, balanced {int(balanced.sum())} of 16 (from upright "
                  f"{float(jnp.mean(up_returns)):.0f}, {int(up_balanced.sum())} of 16), {time.time() - t0:.0f} s",
                  flush=True)


if __name__ == "__main__":
    main()
