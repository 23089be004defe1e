"""Per-link arrays and the operations over the links that every recursive algorithm uses.

Layout: a per-link quantity is an array of shape ``(n, *batch)`` (the links first), a per-link parameter one of shape
``(n, 1, ..., 1)`` that broadcasts against it, or a Python float when it is the same constant for every link (it folds
into the compiled step). The shifts and sums along the links (:func:`prev`, :func:`next_link`, :func:`cumsum`,
:func:`rcumsum`) and the scan over them (:func:`scan`) are the only places the algorithms meet the chain's order.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from lagrange.math import scalar as s
from lagrange.planar.model import PlanarChain


def links_first(x, batch):
    """``(..., n) -> (n, *batch)``, broadcast to the batch shape."""
    x = jnp.broadcast_to(x, batch + x.shape[-1:])
    return jnp.moveaxis(x, -1, 0)


def links_last(x):
    """``(n, *batch) -> (*batch, n)``."""
    return jnp.moveaxis(x, 0, -1)


def param(x, nb: int):
    """A per-link parameter ``(n,)`` shaped ``(n, 1, ..., 1)`` to broadcast against ``(n, *batch)``."""
    return jnp.reshape(x, x.shape + (1,) * nb)


def prev(x, first):
    """``x`` shifted one link outward: ``out[0] = first``, ``out[i] = x[i - 1]``."""
    if s.is_const(x):  # a structural zero (no revolute joint)
        return x
    return jnp.concatenate([jnp.full_like(x[:1], first), x[:-1]], axis=0)


def next_link(x):
    """``x`` shifted one link inward: ``out[i] = x[i + 1]``, ``out[n - 1] = 0``."""
    return jnp.concatenate([x[1:], jnp.zeros_like(x[:1])], axis=0)


def cumsum(x):
    """``sum_{k <= i} x_k``."""
    if s.is_const(x):  # a structural zero
        return x
    return jnp.cumsum(x, axis=0)


def rcumsum(x):
    """``sum_{k >= i} x_k``."""
    return jnp.flip(jnp.cumsum(jnp.flip(x, 0), axis=0), 0)


def batch_shape(*xs):
    """The broadcast batch shape of arrays ``(*batch, n)`` (``None`` entries skipped)."""
    return jnp.broadcast_shapes(*(jnp.shape(x)[:-1] for x in xs if x is not None))


def prepare(chain: PlanarChain, q, qd, *extra):
    """``(batch, dtype, q, qd)`` with ``q`` and ``qd`` in the links-first layout ``(n, *batch)`` of the common dtype
    (``qd`` may be ``None``); ``extra`` arrays only take part in the batch shape and the dtype."""
    batch = batch_shape(q, qd, *extra)
    dtype = jnp.result_type(chain.mass, *(x for x in (q, qd, *extra) if x is not None))
    q = links_first(q.astype(dtype), batch)
    qd = None if qd is None else links_first(qd.astype(dtype), batch)
    return batch, dtype, q, qd


def per_link(x, dtype):
    """A per-link parameter for a scan over the links: a Python float when every link has the same concrete value (it
    folds into the compiled step), else an array of shape (n,) that the scan slices link by link."""
    if isinstance(x, np.ndarray) and x.size and np.all(x == x.flat[0]):
        return float(x.flat[0])
    return jnp.asarray(x, dtype)


def arrays(xs, like):
    """``xs`` (a dict or tuple) with every entry an array shaped like ``like`` (scan outputs and carries)."""
    if isinstance(xs, dict):
        return {key: jnp.broadcast_to(jnp.asarray(v, like.dtype), like.shape) for key, v in xs.items()}
    return tuple(jnp.broadcast_to(jnp.asarray(v, like.dtype), like.shape) for v in xs)


def split_links(xs, params, nb):
    """The scan inputs of per-link arrays ``xs`` (each (n, *batch), a constant or None) and parameters ``params``
    (each (n, 1, ..., 1) as :func:`param` shapes them, a constant or None): the arrays to slice link by link (the
    parameters as (n,)), and the constants (``None`` read as 0) that stay out of the loop."""
    out, consts = {}, {}
    for key, v in (xs | params).items():
        if v is None or s.is_const(v):
            consts[key] = 0.0 if v is None else v
        else:
            out[key] = jnp.reshape(v, v.shape[:1]) if key in params else v
    return out, consts


def scan(body, init, xs, reverse=False):
    """``lax.scan`` over the links, the body rematerialised in reverse mode so that its residuals
    are the carries only (measured at n = 20, batch 1024: gradient compile 1.9 s instead of 15 s,
    and 25% faster). Not unrolled: with the per-link tuple bodies, ``unroll=2`` and ``4`` were slower at
    n = 8 and 32 at batch 1 and 1024 alike (forward 1.5-10x, gradient 1.5-10x) and compiled 2-4x longer."""
    return jax.lax.scan(jax.checkpoint(body), init, xs, reverse=reverse)


def momentum(J, hx, hz, m, w, vx, vz):
    """``I (w, vx, vz)`` for the spatial inertia of mass ``m``, first moment ``(hx, hz)`` and inertia ``J`` about the
    reference point."""
    return (
        s.add(s.sub(s.mul(J, w), s.mul(hz, vx)), s.mul(hx, vz)),
        s.sub(s.mul(m, vx), s.mul(hz, w)),
        s.add(s.mul(hx, w), s.mul(m, vz)),
    )


# ------------------------------------------------------------------ a tree's links


class Topology:
    """The sums and shifts of per-link arrays ``(n, *batch)`` along a chain's tree, for the recursive algorithms.

    On a serial chain they are the cumulative sums and one-link shifts above, the program the chain has always had;
    on a tree the sums over paths, subtrees and children are products with constant 0/1 matrices (``n x n``, the
    tree's path matrix ``P[i, k] = 1`` for ``k`` on the path from the world to ``i``, and its child matrix
    ``C[i, c] = 1`` for the children ``c`` of ``i``), and the scans are still one scan each over all the links, a
    link's carry coming from its parent through a few slots (:func:`_outward_plan`, :func:`_inward_plan`), so a
    branched tree costs about what a chain of as many links costs.
    """

    def __init__(self, chain: PlanarChain):
        self.chain = chain
        self.serial = chain.serial
        n = chain.n
        self.parents = np.asarray(chain.parents)
        self.path = np.zeros((n, n), bool)
        for i in range(n):
            self.path[i, list(chain.path(i))] = True
        self.child = np.zeros((n, n), bool)
        for c, p in enumerate(chain.parents):
            if p >= 0:
                self.child[p, c] = True

    def _dot(self, matrix, x):
        return jnp.tensordot(jnp.asarray(matrix, x.dtype), x, axes=1)

    def path_sum(self, x):
        """``sum_{k on the path from the world to i} x_k`` (a serial chain: :func:`cumsum`)."""
        if self.serial or s.is_const(x):
            return cumsum(x)
        return self._dot(self.path, x)

    def subtree_sum(self, x):
        """``sum_{k in i's subtree, i included} x_k`` (a serial chain: :func:`rcumsum`)."""
        if self.serial:
            return rcumsum(x)
        return self._dot(self.path.T, x)

    def children_sum(self, x):
        """``sum_{c a child of i} x_c`` (a serial chain: :func:`next_link`)."""
        if self.serial:
            return next_link(x)
        return self._dot(self.child, x)

    def parent_value(self, x, world):
        """``x`` of each link's parent, ``world`` for a link of the world (a serial chain: :func:`prev`)."""
        if self.serial or s.is_const(x):
            return prev(x, world)
        shape = (-1,) + (1,) * (x.ndim - 1)
        of_world = jnp.asarray(self.parents < 0).reshape(shape)
        return jnp.where(of_world, jnp.asarray(world, x.dtype), x[np.maximum(self.parents, 0)])

    def scan_outward(self, body, init, xs):
        """``(final carry, ys)``: ``body`` scanned over the links from the world outward, ``ys`` in link order.

        A serial chain is one :func:`scan`. On a tree it is one scan too: each link starts from its parent's carry,
        which is the previous link's, the world's (``init``), or one kept in a slot since the parent was
        scanned (:func:`_outward_plan`); the selection is a few ``select``s per step.
        """
        if self.serial:
            return scan(body, init, xs)
        source, save, slots = _outward_plan(self.chain.parents)

        def step(carry, x):
            current, kept = carry
            src, dst = x.pop("_source"), x.pop("_save")
            start = tuple(jax.lax.select_n(src, c, w, *k) for c, w, *k in zip(current, init, *kept))
            new, y = body(start, x)
            kept = tuple(tuple(jnp.where(dst == k, a, b) for a, b in zip(new, slot)) for k, slot in enumerate(kept))
            return (new, kept), y

        flags = {"_source": jnp.asarray(source, jnp.int32), "_save": jnp.asarray(save, jnp.int32)}
        (carry, _), ys = scan(step, (init, (init,) * slots), xs | flags)
        return carry, ys

    def scan_inward(self, body, init, xs):
        """``(final carry, ys)``: ``body`` scanned over the links from the leaves inward, ``ys`` in link order; each
        link's carry in is the sum of its children's carries out (``init``, zeros, where it has none).

        A serial chain is one reversed :func:`scan`. On a tree it is one too: a child that is not the next link
        deposits its carry into a slot that its parent collects (:func:`_inward_plan`).
        """
        if self.serial:
            return scan(body, init, xs, reverse=True)
        take, collect, deposit, slots = _inward_plan(self.chain.parents)

        def step(carry, x):
            current, kept = carry
            tk, col, dep = x.pop("_take"), x.pop("_collect"), x.pop("_deposit")
            into = tuple(jnp.where(tk, c, z) for c, z in zip(current, init))
            for k, slot in enumerate(kept):
                into = tuple(a + jnp.where(col == k, b, z) for a, b, z in zip(into, slot, init))
            kept = tuple(tuple(jnp.where(col == k, z, b) for b, z in zip(slot, init)) for k, slot in enumerate(kept))
            new, y = body(into, x)
            kept = tuple(tuple(b + jnp.where(dep == k, a, z) for a, b, z in zip(new, slot, init))
                         for k, slot in enumerate(kept))
            return (new, kept), y

        flags = {"_take": jnp.asarray(take), "_collect": jnp.asarray(collect, jnp.int32),
                 "_deposit": jnp.asarray(deposit, jnp.int32)}
        (carry, _), ys = scan(step, (init, (init,) * slots), xs | flags, reverse=True)
        return carry, ys


def _intervals_to_slots(intervals: dict[int, tuple[int, int]]) -> tuple[dict[int, int], int]:
    """Slots for values alive over ``[first, last]`` steps (inclusive), two never sharing a slot while both live."""
    slot_of, free_at = {}, []
    for key, (first, last) in sorted(intervals.items(), key=lambda kv: kv[1]):
        for k, end in enumerate(free_at):
            if end < first:
                slot_of[key], free_at[k] = k, last
                break
        else:
            slot_of[key] = len(free_at)
            free_at.append(last)
    return slot_of, len(free_at)


def _outward_plan(parents: tuple[int, ...]):
    """Per link: where its parent's carry comes from (0: the previous link's, 1: the world's, ``2 + k``: slot ``k``)
    and the slot its own carry is kept in for a later child (-1: none); and the number of slots."""
    n = len(parents)
    later = {p: max(c for c in range(n) if parents[c] == p and c != p + 1)
             for p in set(parents) if p >= 0 and any(parents[c] == p and c != p + 1 for c in range(n))}
    slot_of, slots = _intervals_to_slots({p: (p + 1, last) for p, last in later.items()})
    source = [0 if p == i - 1 and p >= 0 else 1 if p < 0 else 2 + slot_of[p] for i, p in enumerate(parents)]
    save = [slot_of.get(i, -1) for i in range(n)]
    return source, save, slots


def _inward_plan(parents: tuple[int, ...]):
    """Per link, scanned from the last to the first: whether the carry of the link after it flows in (it is its
    child), the slot its other children's carries were deposited in (-1: none), and the slot its own carry is
    deposited in for its parent (-1: none: it flows on to the link before it, its parent, or the world takes it);
    and the number of slots. Steps count in scanning order (link ``n - 1`` first)."""
    n = len(parents)
    step = lambda i: n - 1 - i  # noqa: E731
    deposits = {}
    for c, p in enumerate(parents):
        if p >= 0 and p != c - 1:
            first, last = deposits.get(p, (step(c), step(p)))
            deposits[p] = (min(first, step(c)), last)
    slot_of, slots = _intervals_to_slots(deposits)
    take = [i + 1 < n and parents[i + 1] == i for i in range(n)]
    collect = [slot_of.get(i, -1) for i in range(n)]
    deposit = [slot_of[p] if p >= 0 and p != c - 1 else -1 for c, p in enumerate(parents)]
    return take, collect, deposit, slots
