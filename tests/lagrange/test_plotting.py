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
    task = tasks.DoubleCartpole.rods()
    q, qd, a = _episode(task)
    episode_figure(task, q, a, tmp_path / "full.png", qd=qd, marks=[(0.1, "a mark")])
    episode_figure(task, q, a, tmp_path / "short.png", title="no velocities")
    full, short = Image.open(tmp_path / "full.png"), Image.open(tmp_path / "short.png")
    assert full.size[0] == short.size[0] and full.size[1] > short.size[1]  # three panels against two


def test_default_title_names_the_task_and_whether_it_balanced(tmp_path, monkeypatch):
    """The default title is the task's display name and ``balanced`` of the episode: False on 20 steps from hanging,
    True on an episode held upright."""
    from matplotlib.axes import Axes

    titles = []
    monkeypatch.setattr(Axes, "set_title", lambda self, label, *args, **kwargs: titles.append(label))
    task = tasks.Acrobot.rods()
    q, qd, a = _episode(task)
    episode_figure(task, q, a, tmp_path / "hanging.png")
    upright = jnp.zeros_like(q).at[:, 0].set(jnp.pi)
    episode_figure(task, upright, a, tmp_path / "upright.png")
    cart = tasks.DiffRLCartpole.diffrl()
    episode_figure(cart, *_episode(cart)[::2], tmp_path / "cart.png")
    assert titles == ["acrobot: balanced False", "acrobot: balanced True", "diffrl_cartpole: balanced False"]


def test_animation_has_one_frame_per_every_steps(tmp_path):
    task = tasks.Acrobot.rods()
    q, _, _ = _episode(task)
    episode_animation(task, q, tmp_path / "a.gif", every=5)
    assert Image.open(tmp_path / "a.gif").n_frames == 5  # steps 0, 5, 10, 15, 20
