"""lagrange.plotting: the episode pictures the examples and benchmarks draw."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image

from lagrange import tasks
from lagrange.plotting import episode_animation, episode_figure


def _episode(task, steps=20):
    s = task.reset(jax.random.PRNGKey(0))
    qs, qds, acts = [s.q], [s.qd], []
    for k in range(steps):
        a = jnp.full((task.action_size,), np.sin(0.3 * k))
        s = task.step(s, a)
        qs.append(s.q), qds.append(s.qd), acts.append(a)
    return jnp.stack(qs), jnp.stack(qds), jnp.stack(acts)


def test_figure_with_and_without_velocities(tmp_path):
    task = tasks.double_cartpole()
    q, qd, a = _episode(task)
    episode_figure(task, q, a, tmp_path / "full.png", qd=qd, marks=[(0.1, "a mark")])
    episode_figure(task, q, a, tmp_path / "short.png", title="no velocities")
    full, short = Image.open(tmp_path / "full.png"), Image.open(tmp_path / "short.png")
    assert full.size[0] == short.size[0] and full.size[1] > short.size[1]  # three panels against two


def test_animation_has_one_frame_per_every_steps(tmp_path):
    task = tasks.acrobot()
    q, _, _ = _episode(task)
    episode_animation(task, q, tmp_path / "a.gif", every=5)
    assert Image.open(tmp_path / "a.gif").n_frames == 5  # steps 0, 5, 10, 15, 20
