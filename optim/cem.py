"""The cross-entropy method over flat policy parameters (the paper's gradient-free ablation).

The same loop as :mod:`optim.ce_apg` with no APG steps: each candidate's fitness is its mean
return over ``episodes`` random-start episodes, and the diagonal Gaussian is refitted to the elites.
"""

from __future__ import annotations


from optim import ce_apg


def config(task: str = "acrobot", **overrides) -> ce_apg.CEAPGConfig:
    """The paper's CEM ablation: CE-APG's sampler with ``apg_steps = 0`` and 2000 iterations."""
    width = 32 if task == "double_cartpole" else 16
    return ce_apg.CEAPGConfig(**{"task": task, "width": width, "apg_steps": 0, "iterations": 2000,
                                 "fitness_window": 1, **overrides})


CEMConfig = ce_apg.CEAPGConfig  # a CEM config is a CE-APG config with apg_steps = 0


def make_trainer(cfg: ce_apg.CEAPGConfig, task=None):
    if cfg.apg_steps != 0:
        raise ValueError(f"CEM needs CEAPGConfig.apg_steps == 0, got {cfg.apg_steps} (use optim.ce_apg)")
    return ce_apg.make_trainer(cfg, task)


def make_train(cfg: ce_apg.CEAPGConfig, task=None):
    if cfg.apg_steps != 0:
        raise ValueError(f"CEM needs CEAPGConfig.apg_steps == 0, got {cfg.apg_steps} (use optim.ce_apg)")
    return ce_apg.make_train(cfg, task)


def cem(fn, mean, std, key, *, iterations: int, num_candidates: int, num_elites: int):
    """Plain CEM maximising ``fn(x) -> ()`` over vectors ``x`` (P,); returns the final mean (P,).

    A small, generic form of the loop above, for black-box objectives (``vmap``-ed over candidates).
    """
    import jax
    import jax.numpy as jnp

    if num_elites > num_candidates:
        raise ValueError(f"num_elites must be <= num_candidates ({num_candidates}), got {num_elites}")

    def body(carry, i):
        mu, sd = carry
        x = mu + sd * jax.random.normal(jax.random.fold_in(key, i), (num_candidates,) + mu.shape, mu.dtype)
        f = jax.vmap(fn)(x)
        f = jnp.where(jnp.isfinite(f), f, -jnp.inf)
        elite = x[jnp.argsort(-f)[:num_elites]]
        return (jnp.mean(elite, 0), jnp.sqrt(jnp.mean((mu - elite) ** 2, 0))), jnp.max(f)

    (mu, sd), best = jax.lax.scan(body, (jnp.asarray(mean), jnp.asarray(std)), jnp.arange(iterations))
    return mu, best


__all__ = ["CEMConfig", "config", "make_trainer", "make_train", "cem"]
