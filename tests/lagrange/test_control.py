"""lagrange.control: the linearisation about upright against closed forms and finite differences, the LQR gain
against the Riccati recursion, the saturated LQR and its basin against rollouts by hand and a research result."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange import control, tasks

G = 9.81


def weights(task, r):
    """The research scripts' weights: Q = diag(1 on q, 0.01 on qd), R = r I."""
    n = task.chain.nv
    return np.diag([1.0] * n + [0.01] * n), r * np.eye(task.chain.m)


@functools.cache
def model(name):
    task = tasks.PAPER_TASKS[name].rods()
    return task, *control.linearise(task)


def upright_cartpole():
    """Continuous-time (Jc, Bc) of x = (x, th - pi, dx, dth) about upright, by hand: cart M, pole m with its centre of
    mass lc = l/2 along it at (x + lc sin th, -lc cos th) and inertia m l^2/12; cart force 100 u. Linearised at
    th = pi: [[M + m, -m lc], [-m lc, I + m lc^2]] (ddx, ddth) = (100 u, m g lc (th - pi))."""
    M, m, lc = 10.47, 5.02, 0.5
    Mq = np.array([[M + m, -m * lc], [-m * lc, m / 12 + m * lc**2]])
    stiffness = np.array([[0.0, 0.0], [0.0, m * G * lc]])
    return Mq, stiffness, np.array([100.0, 0.0])


def upright_acrobot():
    """The same for the acrobot (relative angles, links 1 m, 2.5 kg, rods; elbow torque 25 u): at q = (pi, 0)
    M = [[I1 + I2 + m lc^2 + m (l^2 + lc^2 + 2 l lc), I2 + m (lc^2 + l lc)], [., I2 + m lc^2]] and the potential
    -g (m lc cos q1 + m (l cos q1 + lc cos(q1 + q2))) has the stiffness below (negative Hessian)."""
    m, l, lc, I = 2.5, 1.0, 0.5, 2.5 / 12
    Mq = np.array([[2 * I + m * lc**2 + m * (l**2 + lc**2 + 2 * l * lc), I + m * (lc**2 + l * lc)],
                   [I + m * (lc**2 + l * lc), I + m * lc**2]])
    stiffness = G * np.array([[m * lc + m * l + m * lc, m * lc], [m * lc, m * lc]])
    return Mq, stiffness, np.array([0.0, 25.0])


@pytest.mark.parametrize("name, closed_form", [("cartpole", upright_cartpole), ("acrobot", upright_acrobot)])
def test_linearise_is_rk4_of_the_closed_form_linearisation(name, closed_form):
    """At an equilibrium every RK4 stage sits at the equilibrium, so the step's Jacobian is RK4 applied to the
    continuous linearisation exactly: A = sum_k (Jc h)^k / k!, B = sum_k h^k Jc^(k-1) / k! Bc (k <= 4). Agreement
    to float64 round-off: 1e-14 on entries of size <= 1.4 (measured: 4e-16)."""
    task, A, B = model(name)
    Mq, stiffness, gear = closed_form()
    Jc = np.block([[np.zeros((2, 2)), np.eye(2)], [np.linalg.solve(Mq, stiffness), np.zeros((2, 2))]])
    Bc = np.concatenate([np.zeros(2), np.linalg.solve(Mq, gear)])[:, None]
    h = task.dt
    A_want = sum(np.linalg.matrix_power(Jc * h, k) / math.factorial(k) for k in range(5))
    B_want = sum(h**k * np.linalg.matrix_power(Jc, k - 1) / math.factorial(k) for k in range(1, 5)) @ Bc
    assert A.dtype == B.dtype == np.float64 and A.shape == (4, 4) and B.shape == (4, 1)
    np.testing.assert_allclose(A, A_want, rtol=0, atol=1e-14)
    np.testing.assert_allclose(B, B_want, rtol=0, atol=1e-14)
    assert np.max(np.abs(np.linalg.eigvals(A))) > 1  # upright is unstable open loop


def test_linearise_away_from_equilibrium_matches_central_differences():
    """At a moving state and a nonzero action: central differences of ``task.step``, h = 1e-6. Truncation
    h^2 |f'''| / 6 ~ 1e-12; round-off eps |x'| / h ~ 2e-16 * 5 / 1e-6 ~ 1e-9 per evaluation: tolerance 1e-8."""
    task = tasks.DoubleCartpole.rods()
    x0 = np.array([0.3, 2.5, -0.4, 0.7, -1.2, 2.0])
    u0 = np.array([0.3])
    A, B = control.linearise(task, x0, u0)
    step = jax.jit(lambda x, u: jnp.concatenate(task.step(tasks.TaskState(x[:3], x[3:]), u)[:2]))
    h = 1e-6
    fd = [(step(x0 + h * e, u0) - step(x0 - h * e, u0)) / (2 * h) for e in np.eye(6)]
    np.testing.assert_allclose(A, np.stack(fd, axis=1), rtol=0, atol=1e-8)
    np.testing.assert_allclose(B[:, 0], (step(x0, u0 + h) - step(x0, u0 - h)) / (2 * h), rtol=0, atol=1e-8)
    with pytest.raises(ValueError, match="x0"):
        control.linearise(task, x0[:4])
    with pytest.raises(ValueError, match="u0"):
        control.linearise(task, x0, np.zeros(2))


def riccati_by_value_iteration(A, B, Q, R, iterations=200_000):
    """P_{k+1} = Q + A'P A - A'P B (R + B'P B)^-1 B'P A from P = Q, until it stops changing; the gain of the limit."""
    P = Q
    for _ in range(iterations):
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P_next = Q + A.T @ P @ (A - B @ K)
        if np.max(np.abs(P_next - P)) <= 1e-13 * np.max(np.abs(P)):
            return K, P_next
        P = P_next
    raise AssertionError("value iteration did not converge")


@pytest.mark.parametrize("name, r", [("cartpole", 1.0), ("cartpole", 1e2), ("acrobot", 1.0), ("acrobot", 1e2)])
def test_lqr_gain_solves_the_riccati_equation_and_stabilises(name, r):
    """The gain of the Riccati recursion's fixed point to 1e-9 of max |K| (the worst case, the acrobot at R = 100,
    measured 6e-10: the Riccati equation is ill-conditioned there; policy iteration agrees with the recursion to
    1e-11)."""
    task, A, B = model(name)
    Q, R = weights(task, r)
    K = control.lqr_gain(A, B, Q, R)
    K_vi, P = riccati_by_value_iteration(A, B, Q, R)
    np.testing.assert_allclose(K, K_vi, rtol=1e-9, atol=1e-9 * np.max(np.abs(K)))
    # the fixed point: P = Q + K'R K + (A - B K)' P (A - B K), the cost of u = -K x
    closed = A - B @ K
    np.testing.assert_allclose(Q + K.T @ R @ K + closed.T @ P @ closed, P, rtol=1e-9)
    assert np.max(np.abs(np.linalg.eigvals(closed))) < 1


def test_lqr_gain_refuses_bad_arguments_naming_them():
    task, A, B = model("cartpole")
    Q, R = weights(task, 1.0)
    for args, field in [((A[:3], B, Q, R), "A"), ((A, B[:3], Q, R), "B"), ((A, B, Q[:3, :3], R), "Q"),
                        ((A, B, Q, np.eye(2)), "R"), ((A, B, np.diag([1.0, -1.0, 1.0, 1.0]), R), "Q"),
                        ((A, B, Q + np.triu(np.ones((4, 4)), 1), R), "Q"), ((A, B, Q, 0.0 * R), "R"),
                        ((A, B, Q, -R), "R"), ((A, B * np.nan, Q, R), "B")]:
        with pytest.raises(ValueError, match=rf"\b{field} must"):
            control.lqr_gain(*args)
    with pytest.raises(np.linalg.LinAlgError):  # a cart that cannot be pushed cannot be stabilised
        control.lqr_gain(A, 0 * B, Q, R)


@functools.cache
def cartpole_lqr(r=1.0):
    task, A, B = model("cartpole")
    return task, control.lqr_gain(A, B, *weights(task, r))


def test_saturated_lqr_is_the_clipped_gain_about_upright_and_brings_the_cartpole_back():
    task, K = cartpole_lqr()
    controller = control.saturated_lqr(task, K)
    # batched; angles are wrapped (a full turn more is the same lean); small deviations are -K dx, large saturate
    q = np.array([[0.1, np.pi + 0.01], [0.1, 3 * np.pi + 0.01], [0.0, np.pi + 1.0]])
    qd = np.array([[0.2, -0.1], [0.2, -0.1], [0.0, 0.0]])
    u = np.asarray(controller(q, qd))
    assert u.shape == (3, 1)
    np.testing.assert_allclose(u[0], -K @ [0.1, 0.01, 0.2, -0.1], rtol=1e-12)
    np.testing.assert_allclose(u[1], u[0], rtol=1e-12)
    assert u[2, 0] == -1.0 and abs(-K @ [0, 1.0, 0, 0])[0] > 1
    with pytest.raises(ValueError, match="K"):
        control.saturated_lqr(task, K.T)
    # from a 0.05 rad lean at rest, 200 control steps (8 s) end within 1e-6 of upright at rest
    x = control.upright_state(task) + np.array([0.0, 0.05, 0.0, 0.0])
    step = jax.jit(lambda x: jnp.concatenate(task.step(tasks.TaskState(x[:2], x[2:]), controller(x[:2], x[2:]))[:2]))
    for _ in range(200):
        x = step(x)
    assert np.max(np.abs(np.asarray(x) - control.upright_state(task))) < 1e-6


def test_basin_agrees_with_rollouts_by_hand():
    """The judged leans of ``basin`` against a Python loop over ``task.step`` with the same controller: a start
    recovers when its final |dx| < tol; the answer is the last lean of the leading run of recovered starts."""
    task = tasks.Acrobot.rods()
    A, B = control.linearise(task)
    controller = control.saturated_lqr(task, control.lqr_gain(A, B, *weights(task, 1e2)))
    leans, steps = (0.005, 0.02, 0.03, 0.1), 400
    got = control.basin(task, controller, leans=leans, steps=steps)
    step = jax.jit(lambda x: jnp.concatenate(task.step(tasks.TaskState(x[:2], x[2:]), controller(x[:2], x[2:]))[:2]))
    errors = np.empty((2, 4))
    for j in (0, 1):
        for k, d in enumerate(leans):
            x = control.upright_state(task)
            x[j] += d
            for _ in range(steps):
                x = step(x)
            errors[j, k] = np.max(np.abs(np.asarray(x) - control.upright_state(task)))
    assert got.joints == (0, 1) and got.final_error.shape == got.recovered.shape == (2, 4)
    np.testing.assert_array_equal(got.recovered, errors < 1e-3)
    ok = errors < 1e-3
    np.testing.assert_allclose(got.final_error[ok], errors[ok], rtol=1e-6, atol=1e-12)
    assert ok[:, 0].all() and not ok[0].all()  # the grid brackets the basin: a real cut, not all or none
    want = [max([0.0] + [d for i, d in enumerate(leans) if ok[j, :i + 1].all()]) for j in (0, 1)]
    np.testing.assert_array_equal(got.largest_recovered_lean, want)
    for kwargs, field in [({"leans": (0.1, 0.05)}, "leans"), ({"steps": 0}, "steps"), ({"tol": 0.0}, "tol"),
                          ({"joints": (2,)}, "joints")]:
        with pytest.raises(ValueError, match=field):
            control.basin(task, controller, **{"leans": leans, "steps": 1, **kwargs})


def test_basin_reproduces_the_research_result_on_the_cartpole():
    """research/results/upright_basin_cartpole.json (float32, 3000 steps, the full lean grid): R = 1 recovers up to
    0.3 rad (0.5 falls), R = 100 from every lean up to 1 rad; its gains to float32 round-off."""
    leans = (0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0)
    recorded = {1.0: ([-0.7736921414235773, 5.942986401420172, -0.8388774111368164, 1.4457077270921903], 0.3, 11),
                1e2: ([-0.08192914447807052, 3.5470035963499282, -0.18420568909377308, 0.8311339008994264], 1.0, 14)}
    with jax.enable_x64(False):
        task = tasks.Cartpole.rods()
        assert control.upright_state(task).dtype == np.float32
        A, B = control.linearise(task)
        for r, (gain, largest, recovered) in recorded.items():
            K = control.lqr_gain(A, B, *weights(task, r))
            np.testing.assert_allclose(K[0], gain, rtol=1e-5)
            got = control.basin(task, control.saturated_lqr(task, K), leans=leans, steps=3000)
            assert got.largest_recovered_lean.tolist() == [largest]
            assert got.recovered[0].tolist() == [True] * recovered + [False] * (14 - recovered)
