"""3-D rotations, quaternions and spatial vectors on arrays with any leading dimensions.

A 3-vector is an array ``(..., 3)``, a rotation ``(..., 3, 3)`` (world from body), a quaternion ``(..., 4)`` in MuJoCo's
order ``(w, x, y, z)``. A spatial *motion* ``(w, v)`` (angular velocity, velocity of the body point at the reference
point) and a spatial *force* ``(n, f)`` (moment about the reference point, force) are arrays ``(..., 6)``, angular
part first; a spatial matrix ``(..., 6, 6)``. Products are written as broadcast multiplies and sums over the small
axes, so that XLA fuses them with their neighbours instead of emitting a small matrix product each.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax
import numpy as np



def eye3(dtype):
    """The 3x3 identity in ``dtype`` (a function, not a module constant: importing lagrange must not start JAX)."""
    return jnp.eye(3, dtype=jax.dtypes.canonicalize_dtype(dtype))


def matvec(A, x):
    """``A x`` over the last axes."""
    return jnp.sum(A * x[..., None, :], axis=-1)


def tmatvec(A, x):
    """``A^T x`` over the last axes."""
    return jnp.sum(A * x[..., :, None], axis=-2)


def matmul(A, B):
    """``A B`` over the last two axes."""
    return jnp.sum(A[..., :, :, None] * B[..., None, :, :], axis=-2)


def take(a, index, axis):
    """``jnp.take(a, index, axis)`` for static, in-bounds indices (a NumPy array): a static slice where ``index`` is a
    run of consecutive entries, else one gather without bounds handling (``jnp.take`` pads with a select per call)."""
    index = np.asarray(index)
    axis = axis % a.ndim
    if index.ndim == 1 and index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return lax.slice_in_dim(a, int(index[0]), int(index[0]) + index.size, axis=axis)
    where = (slice(None),) * axis + (index.astype(np.uint32),)
    return a.at[where].get(mode="promise_in_bounds", unique_indices=len(set(index.reshape(-1))) == index.size)


def _roll(a, k):
    """The last axis's entries ``(a_k, a_k+1, ...)`` cyclically: two slices and a concatenation (no gather)."""
    return jnp.concatenate([a[..., k:], a[..., :k]], axis=-1)


def cross(a, b):
    """``a x b``, as two cyclic shifts of each factor (a handful of operations, which fuse)."""
    return _roll(a, 1) * _roll(b, 2) - _roll(a, 2) * _roll(b, 1)


def skew(a):
    """``[a]x``: ``skew(a) @ b = a x b``."""
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    o = jnp.zeros_like(x)
    return jnp.stack([o, -z, y, z, o, -x, -y, x, o], axis=-1).reshape(a.shape[:-1] + (3, 3))


def axis_rotation(axis, c, s):
    """The rotation by the angle of cosine ``c`` and sine ``s`` (``(...)``) about the unit ``axis`` (``(..., 3)``):
    ``a a^T + c (1 - a a^T) + s [a]x``."""
    aa = axis[..., :, None] * axis[..., None, :]
    return aa + c[..., None, None] * (eye3(aa.dtype) - aa) + s[..., None, None] * skew(axis)


def quat_to_matrix(q, xp=jnp):
    """The rotation of a unit quaternion ``(w, x, y, z)`` (MuJoCo's ``mju_quat2Mat``); ``xp=numpy`` computes it in NumPy
    (a concrete placement, while tracing or reading a model)."""
    w, x, y, z = (q[..., i] for i in range(4))
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    wx, wy, wz, xy, xz, yz = w * x, w * y, w * z, x * y, x * z, y * z
    return xp.stack([xp.stack([ww + xx - yy - zz, 2 * (xy - wz), 2 * (xz + wy)], -1),
                     xp.stack([2 * (xy + wz), ww - xx + yy - zz, 2 * (yz - wx)], -1),
                     xp.stack([2 * (xz - wy), 2 * (yz + wx), ww - xx - yy + zz], -1)], axis=-2)


def quat_multiply(a, b):
    """The Hamilton product ``a b``."""
    aw, ax, ay, az = (a[..., i] for i in range(4))
    bw, bx, by, bz = (b[..., i] for i in range(4))
    return jnp.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                      aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def normalize_quat(q):
    """``q / |q|``."""
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def rotvec_quat(r):
    """The unit quaternion of the rotation vector ``r``: ``(cos(|r|/2), sin(|r|/2) r/|r|)``, its value and its
    gradient exact at ``r = 0`` (a series below ``|r|^2 < 1e-8``: the square root's gradient at 0, NaN in a plain
    formula, never reaches the result)."""
    t2 = jnp.sum(r * r, axis=-1, keepdims=True)
    small = t2 < 1e-8
    t = jnp.sqrt(jnp.where(small, 1.0, t2))
    c = jnp.where(small, 1.0 - t2 / 8.0 + t2 * t2 / 384.0, jnp.cos(t / 2))
    k = jnp.where(small, 0.5 - t2 / 48.0 + t2 * t2 / 3840.0, jnp.sin(t / 2) / t)
    return jnp.concatenate([c, k * r], axis=-1)


def quat_integrate(q, w, h):
    """``q`` turned by the body-frame angular velocity ``w`` for ``h`` seconds and normalised: ``q exp(h w / 2)``,
    MuJoCo's ``mju_quatIntegrate``."""
    return normalize_quat(quat_multiply(q, rotvec_quat(h * w)))


def quat_difference(qa, qb):
    """The rotation vector from ``qb`` to ``qa`` in ``qb``'s frame, ``log(qb^-1 qa)`` (MuJoCo's ``mju_subQuat``), its
    value and gradient finite where ``qa = qb``."""
    d = quat_multiply(qb * jnp.asarray([1.0, -1.0, -1.0, -1.0], qb.dtype), qa)
    d = jnp.where(d[..., :1] < 0, -d, d)  # the shorter way round: angle in [0, pi]
    v2 = jnp.sum(d[..., 1:] ** 2, axis=-1, keepdims=True)
    small = v2 < 1e-16
    sn = jnp.sqrt(jnp.where(small, 1.0, v2))
    k = jnp.where(small, 2.0 / d[..., :1], 2 * jnp.arctan2(sn, d[..., :1]) / sn)  # -> 2 / w as |v| -> 0
    return k * d[..., 1:]


def cross_motion(m1, m2):
    """``m1 x m2`` of motions: ``(w1 x w2, w1 x v2 + v1 x w2)``."""
    w1, v1, w2, v2 = m1[..., :3], m1[..., 3:], m2[..., :3], m2[..., 3:]
    return jnp.concatenate([cross(w1, w2), cross(w1, v2) + cross(v1, w2)], axis=-1)


def cross_force(m, f):
    """``m x* f`` of a motion and a force: ``(w x n + v x f, w x f)``."""
    w, v, n, fl = m[..., :3], m[..., 3:], f[..., :3], f[..., 3:]
    return jnp.concatenate([cross(w, n) + cross(v, fl), cross(w, fl)], axis=-1)


def rigid_apply(m, h, J, motion):
    """``I (w, v) = (J w + h x v, m v - h x w)`` for the rigid inertia of mass ``m`` (``(...)``), first moment ``h``
    and rotational inertia ``J`` about the reference point."""
    w, v = motion[..., :3], motion[..., 3:]
    return jnp.concatenate([matvec(J, w) + cross(h, v), m[..., None] * v - cross(h, w)], axis=-1)


def rigid_matrix(m, h, J):
    """The rigid inertia as a 6x6 matrix ``[[J, [h]x], [-[h]x, m 1]]``."""
    H = skew(h)
    mass = jnp.broadcast_to(m[..., None, None] * eye3(J.dtype), J.shape)  # m may lack the batch's axes
    return jnp.concatenate([jnp.concatenate([J, H], axis=-1), jnp.concatenate([-H, mass], axis=-1)], axis=-2)
