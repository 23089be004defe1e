"""``optim.apg.apg_steps`` with a replaceable objective, for experiments that change the APG loss.

The library's APG loss is minus the mean batch return; an experiment that adds a term to it (or trains on another
reward) passes ``objective(task, eps) -> (loss, reported_return)`` and patches the result into ``optim.ce_apg``
(``ce_apg.apg_steps = apg_steps_with(objective)``). Everything else is ``optim.apg.apg_steps``'s loop: fresh Adam,
one key per step, the first non-finite loss or gradient freezes the parameters, the normaliser updated on each batch's
observations. ``reported_return`` is what the candidate's fitness averages (the last ``fitness_window`` values).
"""

import jax
import jax.numpy as jnp
import optax

from optim.apg import APGResult, episode


def paper_objective(task, eps):
    """The library's objective: minus the mean return, and that return."""
    ret = jnp.mean(eps.ret)
    return -ret, ret


def apg_steps_with(objective=paper_objective):
    """An ``apg_steps`` with the signature of :func:`optim.apg.apg_steps` whose loss is ``objective``."""

    def apg_steps(task, unravel, params, normalizer, key, *, steps, episodes, learning_rate, truncation=None):
        adam = optax.scale_by_adam()

        def loss(p, norm, keys):
            eps = jax.vmap(lambda k: episode(task, unravel(p), norm, k, truncation=truncation))(keys)
            value, reported = objective(task, eps)
            return value, (eps.obs, reported)

        grad_fn = jax.value_and_grad(loss, has_aux=True)

        def body(carry, i):
            p, opt, norm, ok = carry
            keys = jax.random.split(jax.random.fold_in(key, i), episodes)
            (value, (obs, reported)), g = grad_fn(p, norm, keys)
            good = ok & jnp.isfinite(value) & jnp.all(jnp.isfinite(g))
            upd, opt2 = adam.update(jnp.where(good, g, 0.0), opt)
            keep = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(good, a, b), new, old)
            p2, opt2 = keep(p - learning_rate * upd, p), keep(opt2, opt)
            if norm is not None:
                norm = keep(norm.update(obs), norm)
            return (p2, opt2, norm, good), reported

        init = (params, adam.init(params), normalizer, jnp.asarray(True))
        (p, _, norm, ok), returns = jax.lax.scan(body, init, jnp.arange(steps))
        return APGResult(p, norm, returns, ok & jnp.all(jnp.isfinite(returns)))

    return apg_steps
