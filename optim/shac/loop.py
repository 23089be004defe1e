"""SHAC's host loop: epochs under a tqdm bar with periodic deterministic evaluation."""

from __future__ import annotations

import jax
import numpy as np

from optim.shac.trainer import Trainer


def run(trainer: Trainer, key, *, epochs: int | None = None, eval_every: int = 25, eval_episodes: int = 16,
        eval_key=None, progress: bool = True):
    """Run ``trainer.update`` for ``epochs`` epochs (default: the config's) on the host with a tqdm bar.

    Every ``eval_every`` epochs (and after the last) the deterministic policy is evaluated on
    ``eval_episodes`` random starts drawn from ``eval_key`` (the same starts every time). Returns
    ``(state, history, curve)``: ``history`` has one dict of floats per epoch (cumulative
    ``env_steps`` and ``elapsed`` seconds, evaluation time excluded), ``curve`` one dict per evaluation
    (``epoch``, ``env_steps``, ``elapsed``, ``return``, ``return_std``, ``balanced``).
    """
    import time

    from tqdm.auto import tqdm

    epochs = trainer.config.epochs if epochs is None else epochs
    if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
        raise ValueError(f"epochs must be an integer >= 1, got {epochs!r}")
    if isinstance(eval_every, bool) or not isinstance(eval_every, int) or eval_every < 1:
        raise ValueError(f"eval_every must be an integer >= 1, got {eval_every!r}")
    eval_key = jax.random.PRNGKey(10_000) if eval_key is None else eval_key
    state = trainer.init(key)
    history, curve = [], []
    env_steps, elapsed, last_return = 0.0, 0.0, float("nan")

    def evaluate(epoch):
        rets, bal = jax.device_get(trainer.evaluate(state, eval_key, eval_episodes))
        curve.append({"epoch": epoch, "env_steps": env_steps, "elapsed": elapsed, "return": float(np.mean(rets)),
                      "return_std": float(np.std(rets)), "balanced": float(np.mean(bal))})

    evaluate(0)
    bar = tqdm(total=epochs, disable=not progress, unit="epoch", dynamic_ncols=True)
    for epoch in range(1, epochs + 1):
        t0 = time.perf_counter()
        state, metrics = trainer.update(state)
        metrics = {k: float(v) for k, v in jax.device_get(metrics).items()}
        elapsed += time.perf_counter() - t0
        env_steps += metrics.pop("env_steps")
        if metrics["episodes"] > 0:
            last_return = metrics["episode_return"]
        metrics.update(epoch=epoch, env_steps=env_steps, elapsed=elapsed)
        history.append(metrics)
        if metrics["nonfinite"]:
            bar.write(f"epoch {epoch}: {int(metrics['nonfinite'])} non-finite update(s) skipped")
        if epoch % eval_every == 0 or epoch == epochs:
            evaluate(epoch)
        bar.set_postfix(train_return=f"{last_return:.0f}", eval_return=f"{curve[-1]['return']:.0f}",
                        value_loss=f"{metrics['value_loss']:.3g}", steps=f"{env_steps:.2e}", refresh=False)
        bar.update(1)
    bar.close()
    return state, history, curve
