"""Scalarising interpreter (research): evaluate a single-environment jaxpr with every array entry a separate (B,)
(batch last, every operation elementwise over the batch), constants folded at trace time."""
import math
import operator

import jax
import jax.extend as jex
import jax.numpy as jnp
import numpy as np
from jax import lax

COUNT = {"ops": 0}


def is_const(x):
    return isinstance(x, (int, float, bool, np.number, np.bool_))


def _op(fn, *xs):
    COUNT["ops"] += 1
    return fn(*xs)


def add(a, b):
    if is_const(a) and is_const(b):
        return a + b
    if is_const(a) and a == 0:
        return b
    if is_const(b) and b == 0:
        return a
    return _op(operator.add, a, b)


def sub(a, b):
    if is_const(a) and is_const(b):
        return a - b
    if is_const(b) and b == 0:
        return a
    if is_const(a) and a == 0:
        return neg(b)
    return _op(operator.sub, a, b)


def neg(a):
    return -a if is_const(a) else _op(operator.neg, a)


def mul(a, b):
    if is_const(a) and is_const(b):
        return a * b
    if is_const(a):
        a, b = b, a
    if is_const(b):
        if b == 0:
            return 0.0
        if b == 1:
            return a
        if b == -1:
            return neg(a)
    return _op(operator.mul, a, b)


def div(a, b):
    if is_const(a) and is_const(b):
        return a / b if not isinstance(a, (int, np.integer)) else type(a)(int(a / b))
    if is_const(a) and a == 0:
        return 0.0
    if is_const(b) and b == 1:
        return a
    return _op(operator.truediv, a, b)


def unary(npf, jf):
    return lambda a: npf(a) if is_const(a) else _op(jf, a)


def binary(npf, jf):
    return lambda a, b: npf(a, b) if is_const(a) and is_const(b) else _op(jf, a, b)


def select(pred, *cases):
    if is_const(pred):
        return cases[int(pred)]
    if all(is_const(c) for c in cases) and len(set(float(c) for c in cases)) == 1:
        return cases[0]
    assert len(cases) == 2
    return _op(jnp.where, pred, cases[1], cases[0])


def total(xs):
    acc = 0.0
    for x in xs:
        acc = add(acc, x)
    return acc


ELEMENTWISE = {
    "add": add, "sub": sub, "mul": mul, "div": div, "neg": neg,
    "sin": unary(math.sin, jnp.sin), "cos": unary(math.cos, jnp.cos), "sqrt": unary(math.sqrt, jnp.sqrt),
    "rsqrt": unary(lambda a: 1 / math.sqrt(a), lax.rsqrt), "abs": unary(abs, jnp.abs),
    "floor": unary(math.floor, jnp.floor), "exp": unary(math.exp, jnp.exp), "log": unary(math.log, jnp.log),
    "tanh": unary(math.tanh, jnp.tanh), "sign": unary(np.sign, jnp.sign),
    "max": binary(max, jnp.maximum), "min": binary(min, jnp.minimum), "atan2": binary(math.atan2, jnp.arctan2),
    "pow": binary(operator.pow, jnp.power),
    "eq": binary(operator.eq, operator.eq), "ne": binary(operator.ne, operator.ne),
    "lt": binary(operator.lt, operator.lt), "le": binary(operator.le, operator.le),
    "gt": binary(operator.gt, operator.gt), "ge": binary(operator.ge, operator.ge),
    "and": binary(lambda a, b: a & b, jnp.logical_and), "or": binary(lambda a, b: a | b, jnp.logical_or),
    "not": unary(lambda a: not a, jnp.logical_not),
}


def to_obj(x):
    """A concrete numpy array -> object array of Python scalars."""
    x = np.asarray(x)
    out = np.empty(x.shape, dtype=object)
    for i, v in np.ndenumerate(x):
        out[i] = v.item()
    return out


def linear_map(fn, operands):
    """A primitive linear in its operands: its 0/1 (or general) coefficient matrix, applied with folding."""
    sizes = [o.size for o in operands]
    n = sum(sizes)
    basis = np.eye(n)
    def f(v):
        parts, off = [], 0
        for o, s in zip(operands, sizes):
            parts.append(v[off:off + s].reshape(o.shape))
            off += s
        return fn(*parts)
    with jax.ensure_compile_time_eval():
        out = np.asarray(jax.vmap(f)(jnp.asarray(basis)))  # (n, *out_shape)
    out_shape = out.shape[1:]
    C = out.reshape(n, -1).T
    flat = np.concatenate([o.reshape(-1) for o in operands])
    res = np.empty(C.shape[0], dtype=object)
    for i in range(C.shape[0]):
        res[i] = total(mul(c, flat[k]) for k, c in enumerate(C[i]) if c != 0)
    return res.reshape(out_shape)


def dot_general(lhs, rhs, dimension_numbers, **_):
    (lc, rc), (lb, rb) = dimension_numbers
    lf = [d for d in range(lhs.ndim) if d not in lc and d not in lb]
    rf = [d for d in range(rhs.ndim) if d not in rc and d not in rb]
    L = lhs.transpose(list(lb) + lf + list(lc))
    R = rhs.transpose(list(rb) + rf + list(rc))
    bs = L.shape[:len(lb)]
    lfs, rfs = L.shape[len(lb):len(lb) + len(lf)], R.shape[len(rb):len(rb) + len(rf)]
    k = int(np.prod(L.shape[len(lb) + len(lf):]))
    nb = int(np.prod(bs))
    L = L.reshape(nb, int(np.prod(lfs)), k)
    R = R.reshape(nb, int(np.prod(rfs)), k)
    out = np.empty((nb, L.shape[1], R.shape[1]), dtype=object)
    for b in range(nb):
        for i in range(L.shape[1]):
            for j in range(R.shape[1]):
                out[b, i, j] = total(mul(L[b, i, t], R[b, j, t]) for t in range(k))
    return out.reshape(tuple(bs) + tuple(lfs) + tuple(rfs))


def cholesky(a, **_):
    n = a.shape[-1]
    assert a.ndim == 2
    L = np.full((n, n), 0.0, dtype=object)
    for j in range(n):
        d = sub(a[j, j], total(mul(L[j, k], L[j, k]) for k in range(j)))
        L[j, j] = ELEMENTWISE["sqrt"](d)
        for i in range(j + 1, n):
            L[i, j] = div(sub(a[i, j], total(mul(L[i, k], L[j, k]) for k in range(j))), L[j, j])
    return L


def triangular_solve(a, b, left_side, lower, transpose_a, conjugate_a, unit_diagonal):
    assert left_side and a.ndim == 2
    A = a.T if transpose_a else a
    low = lower != bool(transpose_a)
    n = A.shape[0]
    cols = b.shape[1] if b.ndim == 2 else None
    B2 = b if b.ndim == 2 else b[:, None]
    X2 = np.empty(B2.shape, dtype=object)
    order = range(n) if low else range(n - 1, -1, -1)
    for c in range(B2.shape[1]):
        for i in order:
            ks = range(i) if low else range(i + 1, n)
            s = sub(B2[i, c], total(mul(A[i, k], X2[k, c]) for k in ks))
            X2[i, c] = s if unit_diagonal else div(s, A[i, i])
    return X2 if cols is not None else X2[:, 0]


def reduce(xs, axes, fn):
    xs = np.moveaxis(xs, axes, list(range(-len(axes), 0)))
    shp = xs.shape[:xs.ndim - len(axes)]
    xs = xs.reshape(shp + (-1,))
    out = np.empty(shp, dtype=object)
    for i in np.ndindex(*shp):
        acc = xs[i][0]
        for x in xs[i][1:]:
            acc = fn(acc, x)
        out[i] = acc
    return out


MOVEMENT = {"slice", "broadcast_in_dim", "concatenate", "squeeze", "reshape", "transpose", "expand_dims", "rev",
            "copy", "copy_p"}


def convert(x, new_dtype, **_):
    def c(v):
        if is_const(v):
            return np.dtype(new_dtype).type(v).item()
        return v.astype(new_dtype)
    return np.vectorize(c, otypes=[object])(x) if x.size else x.copy()


def broadcast_map(f, operands):
    """``f`` applied entry by entry to the operands broadcast against each other."""
    shp = np.broadcast_shapes(*[o.shape for o in operands])
    operands = [np.broadcast_to(o, shp) for o in operands]
    out = np.empty(shp, dtype=object)
    for idx in np.ndindex(*shp):
        out[idx] = f(*[o[idx] for o in operands])
    return out


def eval_jaxpr(jaxpr, consts, *args):
    env = {}

    def read(v):
        if isinstance(v, jex.core.Literal):
            return to_obj(v.val)
        return env[v]

    for v, c in zip(jaxpr.constvars, consts):
        env[v] = to_obj(c) if not isinstance(c, np.ndarray) or c.dtype != object else c
    for v, a in zip(jaxpr.invars, args):
        env[v] = a
    for eqn in jaxpr.eqns:
        ins = [read(v) for v in eqn.invars]
        name, p = eqn.primitive.name, eqn.params
        if name in ELEMENTWISE:
            outs = [broadcast_map(ELEMENTWISE[name], ins)]
        elif name == "integer_pow":
            y = p["y"]
            def ip(a):
                r = 1.0
                for _ in range(abs(y)):
                    r = mul(r, a)
                return div(1.0, r) if y < 0 else r
            outs = [np.vectorize(ip, otypes=[object])(ins[0])]
        elif name == "select_n":
            outs = [broadcast_map(select, ins)]
        elif name in MOVEMENT or name in ("stack",):
            outs = [movement(lambda *a, prim=eqn.primitive, p=p: prim.bind(*a, **p), ins)]
        elif name == "convert_element_type":
            outs = [convert(ins[0], p["new_dtype"])]
        elif name == "iota":
            with jax.ensure_compile_time_eval():
                outs = [to_obj(eqn.primitive.bind(**p))]
        elif name in ("gather", "dynamic_slice", "scatter", "dynamic_update_slice", "pad", "scatter-add",
                      "scatter_add"):
            # operands that are pure indices must be constants; the rest move
            if name == "gather":
                idx = np.vectorize(lambda v: v, otypes=[np.int64])(ins[1]).astype(np.int64)
                fn = lambda o: eqn.primitive.bind(o, jnp.asarray(idx), **p)  # noqa: E731
                outs = [movement(fn, [ins[0]])]
            elif name == "scatter":
                idx = np.vectorize(lambda v: v, otypes=[np.int64])(ins[1]).astype(np.int64)
                fn = lambda o, u: eqn.primitive.bind(o, jnp.asarray(idx), u, **p)  # noqa: E731
                outs = [movement(fn, [ins[0], ins[2]])]
            elif name in ("scatter-add", "scatter_add"):
                idx = np.vectorize(lambda v: v, otypes=[np.int64])(ins[1]).astype(np.int64)
                fn = lambda o, u: eqn.primitive.bind(o, jnp.asarray(idx), u, **p)  # noqa: E731
                outs = [linear_map(fn, [ins[0], ins[2]])]
            elif name == "dynamic_slice":
                starts = [int(i.item()) for i in ins[1:]]
                fn = lambda o: lax.dynamic_slice(o, starts, p["slice_sizes"])  # noqa: E731
                outs = [movement(fn, [ins[0]])]
            elif name == "pad":
                pv = ins[1].item()
                fn = lambda o: lax.pad(o, jnp.asarray(-1, o.dtype), p["padding_config"])  # noqa: E731
                r = movement(fn, [ins[0]], fill=pv)
                outs = [r]
            else:
                raise NotImplementedError(name)
        elif name == "dot_general":
            outs = [dot_general(ins[0], ins[1], **p)]
        elif name == "reduce_sum":
            outs = [reduce(ins[0], list(p["axes"]), add)]
        elif name == "reduce_max":
            outs = [reduce(ins[0], list(p["axes"]), ELEMENTWISE["max"])]
        elif name == "reduce_min":
            outs = [reduce(ins[0], list(p["axes"]), ELEMENTWISE["min"])]
        elif name == "cholesky":
            outs = [cholesky(ins[0], **p)]
        elif name == "triangular_solve":
            outs = [triangular_solve(ins[0], ins[1], **p)]
        elif name in ("pjit", "jit", "closed_call", "core_call"):
            cj = p["jaxpr"]
            outs = eval_jaxpr(cj.jaxpr, cj.consts, *ins)
        elif name in ("remat2", "checkpoint"):
            outs = eval_jaxpr(p["jaxpr"], [], *ins)
        elif name == "custom_jvp_call":
            cj = p["call_jaxpr"]
            outs = eval_jaxpr(cj.jaxpr, cj.consts, *ins)
        elif name == "custom_vjp_call" or name == "custom_vjp_call_jaxpr":
            cj = p.get("call_jaxpr") or p["fun_jaxpr"]
            outs = eval_jaxpr(cj.jaxpr, cj.consts, *ins)
        elif name == "stop_gradient":
            outs = ins
        elif name == "round":
            outs = [np.vectorize(lambda a: float(np.round(a)) if is_const(a) else _op(jnp.round, a),
                                 otypes=[object])(ins[0])]
        else:
            raise NotImplementedError(name)
        if not eqn.primitive.multiple_results:
            assert len(outs) == 1
        for v, o in zip(eqn.outvars, outs):
            if not isinstance(o, np.ndarray):
                o2 = np.empty((), dtype=object)
                o2[()] = o
                o = o2
            env[v] = o
    return [read(v) for v in jaxpr.outvars]


def movement(fn, operands, fill=0.0):
    """A pure data movement ``fn`` of the operands: applied to their entries' indices, which then pick the entries
    (an index of -1 picks ``fill``)."""
    flat = np.concatenate([o.reshape(-1) for o in operands] + [np.array([fill], dtype=object)])
    idxs, off = [], 0
    for o in operands:
        idxs.append(np.arange(off, off + o.size, dtype=np.int64).reshape(o.shape))
        off += o.size
    with jax.ensure_compile_time_eval():
        res = np.asarray(fn(*[jnp.asarray(i) for i in idxs]))
    return flat[res]  # -1 -> fill


def scalarize(fn, *example_args):
    """fn of single-environment arrays -> a function of lists of (B,) arrays (one per entry, flat, row-major)."""
    closed = jax.make_jaxpr(fn)(*example_args)
    shapes = [np.shape(a) for a in example_args]

    def run(*flat_args):
        objs = []
        for shp, flat in zip(shapes, flat_args):
            o = np.empty(int(np.prod(shp)), dtype=object)
            for i, x in enumerate(flat):
                o[i] = x
            objs.append(o.reshape(shp))
        outs = eval_jaxpr(closed.jaxpr, closed.consts, *objs)
        return [list(o.reshape(-1)) for o in outs]

    return run
