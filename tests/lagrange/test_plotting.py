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


def test_convex_hull_keeps_the_corners_counter_clockwise():
    from lagrange.plotting import convex_hull

    rng = np.random.default_rng(0)
    square = np.array([[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]])
    inside = rng.uniform(-4.9, 4.9, (50, 2))
    np.testing.assert_array_equal(convex_hull(np.vstack([inside, square[::-1], square[:2]])), square)
    np.testing.assert_array_equal(convex_hull([[1.0, 2.0], [1.0, 2.0]]), [[1.0, 2.0]])


def test_gait_animation_draws_boxes_from_their_corners(tmp_path):
    """The SNU humanoid's bodies are boxes whose contact points are corners of radius 0: each is drawn as its outline
    seen from the side, so the standing figure's frame holds about the pixels of its side-view silhouette (it was
    drawn as capsules of width 0, an empty frame)."""
    from lagrange.plotting import gait_animation

    task = tasks.SNUHumanoid.diffrl()
    q = jnp.stack([task.reset(jax.random.PRNGKey(0)).q] * 3)
    gait_animation(task, q, tmp_path / "gait.gif")
    frame = np.asarray(Image.open(tmp_path / "gait.gif").convert("RGB")).astype(int)
    blue = np.all(np.abs(frame - np.array([31, 119, 180])) < 40, axis=-1)
    rows = np.flatnonzero(blue.any(axis=1))
    assert blue.sum() > 500  # the pelvis, the legs and the feet
    # from the feet to the pelvis: ~1 m of the 1.33-m view, which spans ~77 % of the frame's height (81 of 161 rows)
    assert rows.max() - rows.min() > 0.4 * frame.shape[0]
