"""A tree's static structure as the algorithms use it: links, kinds, paths and the rounds that compose frames,
built while tracing.

A *link* is one joint and what it carries: the joints of a body with several act in turn, so a body is a chain of
links whose last carries the body, and a body without joints is welded into the link it hangs from. The algorithms
work on all links at once: per joint kind one vectorised operation over that kind's links (:class:`Group`), the
sums along paths and over subtrees as products with the 0/1 matrix :attr:`Structure.path` and its transpose, and the
frames composed from the world by pointer jumping (:attr:`Structure.jumps`): ``ceil(log2(depth))`` rounds in which
every link composes its frame with its current ancestor's and takes that ancestor's ancestor. A step's program thus
has a size set by the joint kinds and ``log2`` of the depth, not by the number of links or levels.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lagrange.math import spatial as al
from lagrange.model.joints import AbstractJoint
from lagrange.model.tree import WORLD, Tree

__all__ = ["Group", "Structure"]


class Group:
    """The links of one joint kind, in link order.

    Attributes:
        kind: the joint class (``Hinge``, ``Slide``, ``Ball``, ``Free``).
        links: their link indices, ``(l,)``.
        dofs: the velocity indices of their dofs, ``(l, kind.nv)``.
        coords: the coordinate indices, ``(l, kind.nq)``.
    """

    def __init__(self, kind, links, dofs, coords):
        self.kind, self.links, self.dofs, self.coords = kind, links, dofs, coords


class Structure:
    """The static structure of a :class:`~lagrange.model.tree.Tree`.

    Attributes:
        joints: the joint of each link (link ``i`` is joint ``i`` in the tree's order).
        link_parent: each link's parent link (``-1``: the world).
        link_body: the body each link's joint moves.
        first: whether a link is its body's first joint (where the body's placement ``pos``, ``quat`` and the
            welded bodies above it apply).
        body_link: the link each body's mass belongs to (``-1``: welded to the world).
        groups: the :class:`Group` of each joint kind the tree has.
        link_order: the permutation that restores link order from the groups' links in turn.
        dof_link: each velocity's link, ``(nv,)``.
        path: ``path[i, k] = 1`` where link ``k`` is on the path from the world to link ``i`` (``i`` included).
        tree_of: each link's tree (its root link's index).
        jumps: the rounds of pointer jumping: per round each link's current ancestor, ``n`` standing for the world
            (whose frame is the identity).
    """

    def __init__(self, tree: Tree):
        self.tree = tree
        joints = tree.joints
        n = len(joints)
        self.joints: tuple[AbstractJoint, ...] = joints
        body_link, link_parent, link_body, first = [], [], [], []
        for i, b in enumerate(tree.bodies):
            above = WORLD if tree.parents[i] == WORLD else body_link[tree.parents[i]]
            for k, _ in enumerate(b.joints):
                link_parent.append(above)
                link_body.append(i)
                first.append(k == 0)
                above = len(link_parent) - 1
            body_link.append(above)
        self.link_parent, self.link_body, self.first = tuple(link_parent), tuple(link_body), tuple(first)
        self.body_link = tuple(body_link)
        self.path = np.zeros((n, n))
        for i in range(n):
            k = i
            while k != WORLD:
                self.path[i, k] = 1.0
                k = link_parent[k]
        self.tree_of = tuple(int(np.flatnonzero(self.path[i])[0]) for i in range(n))
        kinds = []
        for j in joints:
            if type(j) not in kinds:
                kinds.append(type(j))
        self.groups = []
        for kind in kinds:
            links = np.array([i for i in range(n) if type(joints[i]) is kind])
            dofs = np.array([[tree.vadr[i] + k for k in range(kind.nv)] for i in links])
            coords = np.array([[tree.qadr[i] + k for k in range(kind.nq)] for i in links])
            self.groups.append(Group(kind, links, dofs, coords))
        self.link_order = np.argsort(np.concatenate([g.links for g in self.groups]))
        self.dof_link = np.repeat(np.arange(n), [j.nv for j in joints])
        anc = np.array([n if p == WORLD else p for p in link_parent] + [n])
        self.jumps = []
        while np.any(anc[:n] != n):
            self.jumps.append(anc[:n].copy())
            anc = anc[anc]

    @property
    def n(self) -> int:
        """The number of links."""
        return len(self.joints)

    def in_link_order(self, parts, axis):
        """Per-group arrays (links on ``axis``), concatenated and put in link order."""
        return al.take(jnp.concatenate(parts, axis=axis), self.link_order, axis=axis)
