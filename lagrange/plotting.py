"""Pictures of a task episode: angles, velocities and actuation over time (PNG), and the chain moving (GIF); for the
locomotion tasks the gait (:func:`gait_figure`, :func:`gait_animation`: the body's capsules on the ground).

Used by the examples (``swingup.png``, ``swingup.gif``, ``gait.png``, ``gait.gif``) and by research scripts that
draw an episode. Built on
``matplotlib.figure.Figure`` rather than ``pyplot``, so drawing never picks a backend or opens a window, and works
headless. Not imported by ``import lagrange`` (matplotlib is only loaded when a picture is drawn).
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.kinematics import contact_point_positions, positions, tip_positions
from lagrange.model.tree import Tree
from lagrange.tasks import AbstractPoleTask, AbstractTask, TaskState, balanced

__all__ = ["episode_figure", "episode_animation", "gait_figure", "gait_animation"]


def episode_figure(task: AbstractPoleTask, q, actions, path: str, *, qd=None, title: str | None = None,
                   marks: Sequence[tuple[float, str]] = ()) -> None:
    """Draw an episode to ``path`` (PNG): the task's angles (the cart's position on its own axis), the angular
    velocities when ``qd`` is given, and the actuator's force or torque.

    ``q`` (T + 1, n) and ``qd`` (T + 1, n) are the visited coordinates and velocities, ``actions`` (T, m) the
    actions in ``[-1, 1]`` (multiplied by the chain's gear for the plot). ``title`` defaults to the task and whether
    the episode is balanced; ``marks`` are ``(time in s, label)`` pairs drawn as vertical lines on every panel."""
    from matplotlib.figure import Figure

    q = jnp.asarray(q)
    th = np.asarray(jax.vmap(lambda x: task.angles(TaskState(x, jnp.zeros_like(x))))(q))
    t = np.arange(th.shape[0]) * task.dt
    force = np.asarray(actions).reshape(len(t) - 1, -1) * np.asarray(task.chain.gear)
    rows = 3 if qd is not None else 2
    fig = Figure(figsize=(7, 2.4 * rows))
    axes = fig.subplots(rows, 1, sharex=True)
    for i in range(th.shape[1]):
        axes[0].plot(t, th[:, i], label="th1 (0 = upright)" if i == 0 else f"th{i + 1} (0 = straight)")
    if task.cart:  # the cart's position on its own scale (metres; it may drift far where the reward ignores it)
        cart_ax = axes[0].twinx()
        cart_ax.plot(t, np.asarray(q[:, 0]), "k:", label="cart x [m] (right axis)")
        cart_ax.set_ylabel("cart x [m]")
        cart_ax.legend(fontsize=7, loc="lower right")
    axes[0].axhspan(-0.2, 0.2, color="g", alpha=0.1, label="balanced band +-0.2")
    axes[0].set_ylabel("angle [rad]")
    if qd is not None:
        dth = np.asarray(jax.vmap(task.angular_velocities)(TaskState(q, jnp.asarray(qd))))
        for i in range(dth.shape[1]):
            axes[1].plot(t, dth[:, i], label=f"dth{i + 1}")
        axes[1].set_ylabel("velocity [rad/s]")
        axes[1].legend(fontsize=7, loc="upper right")
    axes[-1].plot(t[:-1], force)
    axes[-1].set_ylabel(f"actuation [{'N' if task.cart else 'N m'}]")
    axes[-1].set_xlabel("time [s]")
    for when, label in marks:
        for k, ax in enumerate(axes):
            ax.axvline(when, color="0.5", lw=0.8, ls="--", label=label if k == 0 else None)
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    if title is None:
        title = f"{task.name}: balanced {bool(balanced(task, q))}"
    axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def chain_outline(tree: Tree, q) -> jax.Array:
    """A planar chain drawn as one line: its bodies' origins (the joints) and the last body's tip, as ``(x, z)`` rows
    of the world's x-z plane, shape ``(*batch, bodies + 1, 2)``."""
    points = jnp.concatenate([positions(tree, q), tip_positions(tree, q)[..., -1:, :]], axis=-2)
    return points[..., ::2]


def chain_reach(tree: Tree) -> float:
    """How far a chain reaches from its first joint at most: the sum of its bodies' tips' distances from their
    origins [m]."""
    return float(sum(np.linalg.norm(np.asarray(b.tip)) for b in tree.bodies if b.tip is not None))


def episode_animation(task: AbstractPoleTask, q, path: str, *, every: int | None = None) -> None:
    """Animate the chain through the coordinates ``q`` (T + 1, n) to ``path`` (GIF, one frame every ``every``
    control steps; default about 20 frames per simulated second)."""
    from matplotlib import animation
    from matplotlib.figure import Figure

    every = every or max(1, int(round(0.05 / task.dt)))
    pts = np.asarray(jax.vmap(lambda x: chain_outline(task.chain, x))(jnp.asarray(q)[::every]))
    reach = chain_reach(task.chain) + 0.2
    xs = pts[..., 0]
    fig = Figure(figsize=(6, 3.5) if task.cart else (4, 4))
    ax = fig.subplots()
    xlo, xhi = (min(xs.min() - 0.3, -reach), max(xs.max() + 0.3, reach)) if task.cart else (-reach, reach)
    ax.set_xlim(xlo, xhi)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.axhline(0, color="0.8", lw=0.8)
    (line,) = ax.plot([], [], "o-", lw=3, color="tab:blue", mfc="k")
    text = ax.text(0.02, 0.95, "", transform=ax.transAxes, fontsize=8, va="top")

    def frame(i):
        line.set_data(pts[i, :, 0], pts[i, :, 1])
        text.set_text(f"t = {i * every * task.dt:4.2f} s")
        return line, text

    anim = animation.FuncAnimation(fig, frame, frames=pts.shape[0], blit=False)
    anim.save(path, writer=animation.PillowWriter(fps=int(round(1 / (every * task.dt)))))


def gait_figure(task: AbstractTask, q, actions, path: str, *, rewards=None, title: str | None = None) -> None:
    """Draw a locomotion episode to ``path`` (PNG): the task's ``track`` of the body (the root's x and height, the
    torso's pitch or tilt), the rewards when given, and the actions, against time.

    Args:
        task: a locomotion task (one with ``track(q)``: a :class:`lagrange.tasks.AbstractLocomotion`).
        q: the visited coordinates, shape ``(T + 1, nq)``.
        actions: the actions in ``[-1, 1]``, shape ``(T, m)``.
        path: the PNG file.
        rewards: the rewards, shape ``(T,)``, or None.
        title: the title; default the task's name and the distance run.
    """
    from matplotlib.figure import Figure

    q, actions = np.asarray(q), np.asarray(actions)
    (xl, x), (hl, h), (al_, angle) = ((k, np.asarray(v)) for k, v in task.track(q).items())
    t = np.arange(q.shape[0]) * task.dt
    panels = 4 if rewards is not None else 3
    fig = Figure(figsize=(7, 1.8 * panels))
    axes = fig.subplots(panels, 1, sharex=True)
    axes[0].plot(t, x, label=xl)
    axes[0].plot(t, h, label=hl)
    axes[0].legend(fontsize=7, loc="upper left")
    axes[1].plot(t, angle, color="tab:green")
    axes[1].set_ylabel(al_)
    if rewards is not None:
        axes[2].plot(t[1:], np.asarray(rewards), color="tab:purple", lw=0.8)
        axes[2].set_ylabel("reward")
    axes[-1].plot(t[1:], actions, lw=0.6)
    axes[-1].set_ylabel("actions")
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].set_title(title or f"{task.name}: {x[-1] - x[0]:.1f} m in {t[-1]:.1f} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def gait_animation(task: AbstractTask, q, path: str, *, every: int | None = None, width: float = 4.0,
                   seconds: float | None = 4.0) -> None:
    """Animate a robot on the ground through the coordinates ``q`` (T + 1, n) to ``path`` (GIF): each link's capsules
    (pairs of its contact points, drawn with their radius; a body whose points all have radius 0, a box's corners, as
    the outline of its points seen from the side), the ground, the view following the root.

    Args:
        task: a task whose chain has contact points (the locomotion tasks).
        q: the coordinates, shape ``(T + 1, n)``.
        path: the GIF file.
        every: one frame every ``every`` control steps (default: about 20 frames per simulated second).
        width: the view's width [m].
        seconds: animate the first ``seconds`` of the episode (a gait repeats; the file stays small), or None: all.
    """
    from matplotlib import animation
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Polygon

    chain = task.chain
    every = every or max(1, int(round(0.05 / task.dt)))
    q = np.asarray(q)
    q = q[: None if seconds is None else int(round(seconds / task.dt)) + 1: every]
    pts = np.asarray(jax.vmap(lambda x: contact_point_positions(chain, x))(jnp.asarray(q)))
    # the side view: x and z; a body's points pair up as capsules, an odd first one is a sphere's centre
    pts = pts[..., [0, 2]]
    radius = np.array([c[3] for b in chain.bodies for c in b.contacts])
    counts = [len(b.contacts) for b in chain.bodies]
    firsts = np.cumsum([0] + counts[:-1])
    boxy = [c >= 3 and not np.any(radius[f:f + c]) for f, c in zip(firsts, counts)]  # corners: drawn as outlines
    outlines = [np.arange(f, f + c) for f, c, b in zip(firsts, counts, boxy) if b]
    capsules = [(f + k, f + k + 1) for f, c, b in zip(firsts, counts, boxy) if not b for k in range(c % 2, c - 1, 2)]
    spheres = [f for f, c, b in zip(firsts, counts, boxy) if c % 2 and not b]
    if pts.shape[-2] == 0:
        raise ValueError("gait_animation draws the robot from its contact points; this one has none")
    ground = float(chain.contact.ground)
    top = float(np.max(pts[..., 1] + radius)) + 0.2
    fig = Figure(figsize=(5, 5 * (top - ground + 0.3) / width), dpi=80)
    ax = fig.subplots()
    ax.set_aspect("equal")
    ax.set_ylim(ground - 0.1, top)
    ax.axhspan(ground - 1.0, ground, color="0.85")
    scale = 72 * 5 / width * 0.8  # points per metre at this figure width (the axes span ~80 % of it)
    lines = [ax.plot([], [], lw=2 * radius[a] * scale, solid_capstyle="round", color="tab:blue")[0]
             for a, b in capsules]
    discs = [ax.add_patch(Circle((0, 0), radius[k], color="tab:blue")) for k in spheres]
    shapes = [ax.add_patch(Polygon(np.zeros((3, 2)), color="tab:blue")) for _ in outlines]
    for x in np.arange(np.floor(q[:, 0].min()) - width, q[:, 0].max() + width, 1.0):  # metre marks on the ground
        ax.axvline(x, color="0.7", lw=0.5)
    text = ax.text(0.02, 0.95, "", transform=ax.transAxes, fontsize=8, va="top")

    def frame(i):
        centre = float(q[i, 0])
        ax.set_xlim(centre - width / 2, centre + width / 2)
        for line, (a, b) in zip(lines, capsules):
            line.set_data(pts[i, [a, b], 0], pts[i, [a, b], 1])
        for disc, k in zip(discs, spheres):
            disc.center = (pts[i, k, 0], pts[i, k, 1])
        for shape, idx in zip(shapes, outlines):
            shape.set_xy(convex_hull(pts[i, idx]))
        text.set_text(f"t = {i * every * task.dt:4.2f} s, x = {centre:5.2f} m")
        return lines + discs + shapes + [text]

    anim = animation.FuncAnimation(fig, frame, frames=pts.shape[0], blit=False)
    anim.save(path, writer=animation.PillowWriter(fps=int(round(1 / (every * task.dt)))))


def convex_hull(points) -> np.ndarray:
    """The convex hull of 2-D points, its corners counter-clockwise (Andrew's monotone chain), shape ``(k, 2)``.

    Args:
        points: shape ``(n, 2)``, ``n >= 1``.
    """
    p = np.unique(np.asarray(points, dtype=float), axis=0)  # sorted by x, then y
    if len(p) < 3:
        return p

    def half(ps):
        out = []
        for x in ps:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (x[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (x[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(x)
        return out[:-1]

    return np.array(half(p) + half(p[::-1]))
