"""Checks of a model's parameters: at construction (types, signs, shapes, finite values, a joint that moves nothing,
which :class:`lagrange.chain.Link`, :class:`lagrange.chain.Chain` and :class:`lagrange.Tree` run) and after it
(:func:`check_parameters`, for parameters set by ``eqx.tree_at`` or traced under ``jit``/``grad``, which the dynamics
run).
"""

from __future__ import annotations

import math
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["check_parameters"]


def traced(*xs) -> bool:
    """Whether any of ``xs`` is traced (a value not known while tracing under ``jit``, ``grad`` or ``vmap``)."""
    return any(isinstance(x, jax.core.Tracer) for x in xs)


def concrete(x):
    """The value of ``x`` as a NumPy array, or ``None`` if it is traced (not known yet)."""
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(f"expected a real number, got {x!r} of type {type(x).__name__}") from err


def check_shapes(tree, **arrays) -> None:
    """The last axis of each array against the tree: ``q (..., nq)``, ``u (..., m)``, any other (``qd``, ``qdd``)
    ``(..., nv)``; ``None`` skipped. Raises a ValueError naming the array."""
    for name, x in arrays.items():
        if x is None:
            continue
        size = {"q": tree.nq, "u": tree.m}.get(name, tree.nv)
        shape = jnp.shape(x)
        if len(shape) == 0 or shape[-1] != size:
            what = " (the tree has no motor: pass u=None)" if name == "u" and size == 0 else ""
            raise ValueError(f"{name} must have shape (..., {size}) for this tree{what}, got {shape}")


def check_scalar(name: str, value, *, positive: bool = False, nonnegative: bool = False, optional: bool = False):
    if value is None:
        if optional:
            return None
        raise TypeError(f"Link.{name} must be a real number, got None")
    if isinstance(value, (bool, np.bool_)) or isinstance(value, str):
        raise TypeError(f"Link.{name} must be a real number, got {value!r}")
    try:
        c = concrete(value)
    except TypeError as err:
        raise TypeError(f"Link.{name} must be a real number, got {value!r}") from err
    if c is None:
        return value
    if c.shape != ():
        raise ValueError(f"Link.{name} must be a scalar, got an array of shape {c.shape}")
    v = float(c)
    if not math.isfinite(v):
        raise ValueError(f"Link.{name} must be finite, got {v}")
    if positive and v <= 0:
        raise ValueError(f"Link.{name} must be > 0, got {v}")
    if nonnegative and v < 0:
        raise ValueError(f"Link.{name} must be >= 0, got {v}")
    return value


def check_array(name: str, value, shape: tuple[int, ...] = (), *, nonnegative: bool = False):
    """``value`` as an array of JAX's default float type and of ``shape``, checked real, finite and, with
    ``nonnegative``, ``>= 0``: a NumPy array when concrete (no JAX operation, and a constant even where the model is
    built inside ``jit``, so that the dynamics fold it), a traced value as it is, checked for its shape only
    (:func:`check_parameters` checks it when it is known). Errors name ``name``.

    Raises:
        TypeError: for ``None``, a bool, a string or anything that is not real numbers.
        ValueError: for another shape, a non-finite entry or a negative one where ``nonnegative``.
    """
    what = "a real number" if shape == () else f"real numbers of shape {shape}"
    if value is None or isinstance(value, (bool, np.bool_, str)):
        raise TypeError(f"{name} must be {what}, got {value!r}")
    if isinstance(value, jax.core.Tracer):
        if jnp.shape(value) != shape:
            raise ValueError(f"{name} must have shape {shape}, got {jnp.shape(value)}")
        return value
    try:
        c = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{name} must be {what}, got {value!r}") from err
    if c.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name} must be finite, got {c.tolist()}")
    if nonnegative and np.any(c < 0):
        raise ValueError(f"{name} must be >= 0, got {c.tolist()}")
    out = c.astype(jax.dtypes.canonicalize_dtype(float))
    out.setflags(write=False)  # a model is immutable: its NumPy parameters too
    return out


def check_pair(name: str, value, owner: str = "Link") -> tuple[float, float] | None:
    """``None`` or ``(lo, hi)`` as floats with ``lo < hi``, both finite, else an error naming ``owner.name``."""
    if value is None:
        return None
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{owner}.{name} must be a pair (lower, upper) of numbers or None, got {value!r}") from err
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{owner}.{name} must be finite with lower < upper, got {value!r}")
    return lo, hi


def check_points(name: str, value, owner: str = "Link", coords: tuple[str, ...] = ("x", "z")) -> tuple[tuple, ...]:
    """A sequence of points ``(*coords, radius)`` as tuples of floats (finite, radius >= 0), else an error naming
    ``owner.name``: a chain's ``(x, z, radius)``, a body's ``(x, y, z, radius)``."""
    fields = ", ".join(coords + ("radius",))
    count = {3: "three", 4: "four"}[len(coords) + 1]
    try:
        points = tuple(tuple(float(c) for c in p) for p in value)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{owner}.{name} must be a sequence of points ({fields}), got {value!r}") from err
    for k, p in enumerate(points):
        if len(p) != len(coords) + 1:
            raise ValueError(f"{owner}.{name}[{k}] must be a point ({fields}) of {count} numbers, got {p!r}")
        if not all(math.isfinite(c) for c in p) or p[-1] < 0:
            raise ValueError(f"{owner}.{name}[{k}] must be finite with radius >= 0, got {p!r}")
    return points


def check_point(name: str, value) -> None:
    """``None`` or a pair of finite reals (a point ``(x, z)``), else a ``TypeError``/``ValueError`` naming ``name``."""
    if value is None:
        return
    if isinstance(value, (str, bool, np.bool_)):
        raise TypeError(f"Link.{name} must be a point (x, z) of two real numbers or None, got {value!r}")
    if isinstance(value, jax.core.Tracer):
        if jnp.shape(value) != (2,):
            raise ValueError(f"Link.{name} must be a point (x, z) of shape (2,), got shape {jnp.shape(value)}")
        return
    try:
        c = np.asarray([0.0 if isinstance(v, jax.core.Tracer) else concrete(v) for v in list(value)], dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(f"Link.{name} must be a point (x, z) of two real numbers or None, got {value!r}") from err
    if c.shape != (2,):
        raise ValueError(f"Link.{name} must be a point (x, z) of two real numbers, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"Link.{name} must be finite, got {value!r}")


def check_laws(contact, limits, contact_links: tuple[int, ...], limited: tuple[int, ...]) -> None:
    """A chain's contact and limit laws: of their types, given exactly when some link has contact points (a range),
    else an error naming the links and the way out."""
    from lagrange.model.contact import PenaltyContact
    from lagrange.model.limits import PenaltyLimits

    for field, law, cls, links, points, name, args, example, drop in (
            ("contact", contact, PenaltyContact, sorted(set(contact_links)), "contact points", "contact law",
             "ke, kd, kf, mu", "contacts=[(x, z, radius), ...]", "points"),
            ("limits", limits, PenaltyLimits, list(limited), "a range", "limit law", "ke, kd",
             "range=(lower, upper)", "ranges")):
        if law is not None and not isinstance(law, cls):
            raise TypeError(f"Chain.{field} must be a lagrange.{cls.__name__} or None, got {type(law).__name__}")
        if law is None and links:
            raise ValueError(f"Chain: links {links} have {points} but the chain has no {name}: pass Chain(..., "
                             f"{field}=lagrange.{cls.__name__}({args})), or drop the {drop}")
        if law is not None and not links:
            raise ValueError(f"Chain.{field} is given but no link has {points}: give links Link(..., {example}), or "
                             f"drop {field}")


def check_parents(links: tuple) -> tuple[int, ...]:
    """Each link's parent index (-1: the world), checked to be the world or a link listed before it."""
    out = []
    for i, lk in enumerate(links):
        p = i - 1 if lk.parent is None else lk.parent
        if not -1 <= p < i:
            raise ValueError(
                f"Chain.links[{i}].parent must be -1 (the world) or the index of a link listed before it (0..{i - 1}), "
                f"got {p}: list every link after its parent (which also rules out cycles)"
            )
        out.append(p)
    return tuple(out)


def is_zero(x) -> bool:
    c = concrete(x)
    return c is not None and float(c) == 0.0


def value_of(x):
    """``x`` as a NumPy array if it is concrete (so that arithmetic on it is not a JAX operation), else as it is."""
    return x if isinstance(x, jax.core.Tracer) else np.asarray(x)


def stack(values, dtype):
    """Per-link scalars (or one scalar) as a JAX array of ``dtype``: stacked in NumPy and transferred when every
    value is concrete, which runs no JAX computation; with ``jax.numpy`` when one is traced."""
    if isinstance(values, (list, tuple)):
        if any(isinstance(v, jax.core.Tracer) for v in values):
            return jnp.stack([jnp.asarray(v, dtype=dtype) for v in values])
        return jax.device_put(np.stack([np.asarray(v, dtype=dtype) for v in values]))
    if isinstance(values, jax.core.Tracer):
        return jnp.asarray(values, dtype=dtype)
    return jax.device_put(np.asarray(values, dtype=dtype))


def stack_points(points, dtype):
    """Points ``(x, z)`` as a JAX array ``(k, 2)`` of ``dtype``, like :func:`_stack` (NumPy when all are concrete)."""
    traced = any(isinstance(v, jax.core.Tracer) for v in points)
    if traced or any(any(isinstance(c, jax.core.Tracer) for c in v) for v in points):
        return jnp.stack([jnp.stack([jnp.asarray(c, dtype=dtype) for c in v]) if not isinstance(v, jax.core.Tracer)
                          else jnp.asarray(v, dtype=dtype) for v in points])
    return jax.device_put(np.stack([np.asarray([np.asarray(c, dtype=dtype) for c in v], dtype=dtype) for v in points]))


def _on_axis(links: tuple, parents: tuple[int, ...], j: int, i: int, com) -> bool:
    """Whether link ``i``'s centre of mass stays on revolute joint ``j``'s axis at every configuration: it sits on
    its own joint (``com = 0``) and every joint on the path from ``j`` to it is revolute and sits on its parent's
    joint (a parent of zero length, or an attach point at the parent's origin)."""
    if com is None or float(com) != 0.0:
        return False
    k = i
    while k != j:
        p = parents[k]
        attach = links[k].attach
        at_origin = is_zero(links[p].length) if attach is None else all(is_zero(c) for c in attach)
        if links[k].joint != "revolute" or not at_origin:
            return False
        k = p
    return True


def _subtree(parents: tuple[int, ...], j: int) -> list[int]:
    """Link ``j`` and every link below it, in order."""
    inside = {j}
    for i in range(j + 1, len(parents)):
        if parents[i] in inside:
            inside.add(i)
    return sorted(inside)


def check_every_joint_moves_something(links: tuple, parents: tuple[int, ...]) -> None:
    """Raise if a joint's diagonal entry of the mass matrix is zero at every configuration (then so is its
    determinant). ``M_jj = sum_{i below j} (m_i |dc_i/dq_j|^2 + I_i [joint j revolute]) + armature_j`` (``i`` over
    ``j``'s subtree, ``j`` included): a prismatic joint moves the mass of every link of its subtree
    (``|dc_i/dq_j| = 1``); a revolute one moves their inertia and every mass off its axis. A sum of non-negative terms,
    so it vanishes identically exactly when each term does. A parameter not known yet (traced) counts as non-zero.
    Checked on the parameters alone, without computing ``M``."""
    mass = [concrete(lk.mass) for lk in links]
    length = [concrete(lk.length) for lk in links]
    com = [length[i] / 2 if lk.com is None and length[i] is not None else concrete(lk.com)
           for i, lk in enumerate(links)]
    # a centre of mass off the link's line is off every joint's axis
    com = [c if is_zero(lk.com_normal) else None for c, lk in zip(com, links)]
    inertia = [
        (mass[i] * length[i] ** 2 / 12 if mass[i] is not None and length[i] is not None else None)
        if lk.inertia is None
        else concrete(lk.inertia)
        for i, lk in enumerate(links)
    ]

    def zero(x):
        return x is not None and float(x) == 0.0

    for j, joint in enumerate(links):
        if not is_zero(joint.armature):
            continue
        tail = _subtree(parents, j)
        if joint.joint == "prismatic":
            if all(zero(mass[i]) for i in tail):
                raise ValueError(
                    f"Chain has a singular mass matrix: prismatic joint {j} moves no mass (links {tail} have zero "
                    f"mass); give one of links {tail} a mass > 0 or joint {j} an armature > 0"
                )
            continue
        massless = [i for i in tail if zero(mass[i]) and zero(inertia[i])]
        on_axis = [i for i in tail if zero(inertia[i]) and not zero(mass[i]) and _on_axis(links, parents, j, i, com[i])]
        if len(massless) + len(on_axis) == len(tail):
            why = []
            if massless:
                why.append(f"links {massless} have zero mass and zero inertia")
            if on_axis:
                why.append(f"links {on_axis} have zero inertia and their centre of mass on joint {j}'s axis")
            raise ValueError(
                f"Chain has a singular mass matrix: revolute joint {j} moves no mass, inertia or armature "
                f"({'; '.join(why)}); give one of links {tail} an inertia > 0 (or a mass off the joint's axis), "
                f"or joint {j} an armature > 0"
            )


def check_parameters(tree: eqx.Module, *, at_run_time: bool = True) -> eqx.Module:
    """Check every parameter of a tree against its rule, including those that skipped the constructor.

    The rules: masses, damping, armature and stiffness >= 0, the inertias' diagonals >= 0, gears > 0, the contact
    and limit laws' parameters as their constructors require (``ke > 0``, ``kd``, ``kf``, ``mu >= 0``), everything
    finite. The parameters that did not pass through the constructors are those set by ``eqx.tree_at`` or traced
    under ``jit``/``grad``/``vmap`` (a fit's parameters); every function of :mod:`lagrange.dynamics` calls this.

    A concrete parameter is checked now, in NumPy; a traced one when it is computed, by ``eqx.error_if`` tied to the
    returned tree's leaves (only with ``at_run_time=True``). Either way the error names the leaf
    (``Chain.bodies[1].mass``, ``Tree.bodies[3].joints[0].damping``) and the rule.

    Args:
        tree: the :class:`lagrange.Tree` (a :class:`lagrange.chain.Chain` is one).
        at_run_time: also check traced parameters at run time (a few comparisons per call).

    Returns:
        The tree (with the run-time checks tied to its traced parameters).

    Raises:
        ValueError: (now) for a concrete parameter that breaks its rule.
        equinox.EquinoxRuntimeError: (when run) for a traced one.
    """
    return _check_tree(tree, at_run_time)


def _words(rule: str) -> str:
    return rule if rule.startswith("finite") else f"{rule} and finite"


_TREE_RULES = {"mass": (">= 0", lambda x: x < 0), "damping": (">= 0", lambda x: x < 0),
               "armature": (">= 0", lambda x: x < 0), "stiffness": (">= 0", lambda x: x < 0),
               "gear": ("> 0", lambda x: ~(x > 0)), "ke": ("> 0", lambda x: ~(x > 0)), "kd": (">= 0", lambda x: x < 0),
               "kf": (">= 0", lambda x: x < 0), "mu": (">= 0", lambda x: x < 0),
               "inertia": ("on its diagonal >= 0", lambda x: (x < 0) & np.eye(3, dtype=bool))}


def _check_tree(tree, at_run_time: bool):
    """:func:`check_parameters`: every leaf finite and by its name's rule; errors name the leaf's path."""
    leaves, treedef = jax.tree_util.tree_flatten_with_path(tree)
    out, changed = [], False
    for path, x in leaves:
        name = type(tree).__name__ + jax.tree_util.keystr(path)
        rule, broken = _TREE_RULES.get(getattr(path[-1], "name", ""), ("finite", lambda v: v != v))
        if not isinstance(x, jax.core.Tracer):
            v = np.asarray(x, dtype=float)
            if np.any(broken(v) | ~np.isfinite(v)):
                raise ValueError(f"{name} must be {_words(rule)}, got {v.tolist()} (a value set after construction: "
                                 "by eqx.tree_at, or traced)")
        elif at_run_time:
            x = eqx.error_if(x, jnp.any(broken(x) | ~jnp.isfinite(x)),
                             f"{name} must be {_words(rule)} (a value traced or set after construction breaks it)")
            changed = True
        out.append(x)
    return jax.tree_util.tree_unflatten(treedef, out) if changed else tree
