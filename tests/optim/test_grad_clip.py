"""The one gradient clip (optim/grad_clip.py) in its two conventions, against the formulas by hand: PyTorch's
``clip_grad_norm_`` (``max / (norm + 1e-6)``, SHAC's) leaves the norm slightly below the bound; the exact one (APG's)
brings it to the bound to round-off and leaves a zero gradient zero; None clips nothing; the norm returned is the one
before clipping."""

import jax.numpy as jnp
import numpy as np

from optim.grad_clip import clip_grad_norm


def test_both_conventions_by_hand():
    grads = {"w": jnp.array([[3.0, 0.0], [0.0, 4.0]]), "b": jnp.array([12.0])}  # global norm 13
    flat = np.array([3.0, 4.0, 12.0])
    clipped, norm = clip_grad_norm(grads, 1.0)
    assert float(norm) == 13.0
    np.testing.assert_array_equal(clipped["b"], grads["b"] * min(1.0, 1.0 / (13.0 + 1e-6)))
    assert 1.0 - 1e-6 < float(np.linalg.norm(np.concatenate([np.ravel(v) for v in clipped.values()]))) < 1.0
    exact, norm = clip_grad_norm(flat, 1.0, eps=None)
    np.testing.assert_allclose(np.linalg.norm(exact), 1.0, rtol=1e-15)
    np.testing.assert_array_equal(exact, flat * (1.0 / 13.0))
    zero, norm = clip_grad_norm(np.zeros(3), 1.0, eps=None)  # max(norm, tiny): no 0 / 0
    assert float(norm) == 0.0 and not np.any(zero) and np.all(np.isfinite(zero))
    given, norm = clip_grad_norm(flat, 1.0, norm=26.0, eps=None)  # the caller's norm (APG masks a bad step's)
    np.testing.assert_array_equal(given, flat * (1.0 / 26.0))
    same, norm = clip_grad_norm(grads, None)
    assert same is grads and float(norm) == 13.0
    loose, _ = clip_grad_norm(flat, 20.0, eps=None)
    np.testing.assert_array_equal(loose, flat)  # inside the bound: the factor is exactly 1
