"""Config validation (optim/validate.py and every algorithm's ``__post_init__``): every field of every config refuses a
bad value with a ``ValueError`` that names the class and the field (a field added without a check fails the coverage
test below); the cross-field rules (elites <= candidates, fitness window <= APG steps, the warm-up, minibatches) name
theirs; ``CEMConfig`` refuses APG steps and SHAC a custom objective; and the check functions themselves."""

import dataclasses
import math

import numpy as np
import pytest

from optim import APGConfig, CEAPGConfig, CEMConfig, PAPGConfig, SHACConfig
from optim.validate import check_bool, check_int, check_positive, check_probability, check_real

# (config class, field, bad value): one or more per field of every config
_INNER = [  # the fields InnerAPGConfig gives CE-APG, CEM and PAPG
    ("iterations", 0), ("iterations", True), ("iterations", 2.0),
    ("episodes", 0), ("episodes", None),
    ("lr_start", -1e-3), ("lr_start", 0.0), ("lr_start", float("inf")), ("lr_start", "fast"),
    ("lr_end", float("nan")), ("lr_end", 0.0),
    ("fitness_window", 0),
    ("normalize", 1), ("normalize", "yes"),
    ("truncation", 0), ("truncation", 2.5),
    ("max_grad_norm", 0.0), ("max_grad_norm", -1.0), ("max_grad_norm", float("nan")),
]
_CE = [  # CEAPGConfig's own fields (CEMConfig inherits them)
    ("num_candidates", 0), ("num_candidates", False),
    ("num_elites", 0),
    ("init_std", -0.1), ("init_std", float("nan")),
    ("upright_starts", 1.5), ("upright_starts", -0.1),
    ("train_noise", -0.1), ("train_noise", float("inf")),
    ("warmup_horizons", "100"), ("warmup_horizons", 100),
    ("warmup_iterations", 0),
    ("warmup_upright", 1.5), ("warmup_upright", -0.5),
    ("authors_normalizer", 1), ("authors_normalizer", None),
]
BAD_FIELDS = (
    [(CEAPGConfig, f, v) for f, v in _INNER + _CE + [("apg_steps", -1), ("apg_steps", 1.5)]]
    + [(CEMConfig, f, v) for f, v in _INNER + _CE + [("apg_steps", 3)]]
    + [(PAPGConfig, f, v) for f, v in _INNER + [("apg_steps", 0), ("num_runs", 0), ("num_runs", True)]]
    + [(APGConfig, f, v) for f, v in [
        ("iterations", 0), ("steps_per_iteration", 0), ("steps_per_iteration", True), ("episodes", 0),
        ("learning_rate", -1.0), ("learning_rate", 0.0), ("learning_rate", float("nan")), ("normalize", 0),
        ("truncation", 0), ("max_grad_norm", 0.0), ("max_grad_norm", "big")]]
    + [(SHACConfig, f, v) for f, v in [
        ("num_envs", 0), ("num_envs", True), ("short_horizon", 0), ("iterations", 0), ("iterations", True),
        ("gamma", 1.5), ("gamma", 0.0), ("lam", -0.1), ("lam", 1.1), ("critic_iterations", -1),
        ("critic_minibatches", 0), ("critic_minibatches", 10**6), ("target_alpha", 1.5), ("actor_lr", 0.0),
        ("critic_lr", -1e-3), ("lr_end", float("inf")), ("adam_b1", 1.0), ("adam_b2", -0.1), ("adam_eps", 0.0),
        ("actor_grad_norm", 0.0), ("critic_grad_norm", -1.0), ("critic_units", (64, 0)), ("critic_units", ()),
        ("critic_units", [64, 64]), ("normalize", 1), ("use_critic", "no")]]
)


@pytest.mark.parametrize("cls, field, value", BAD_FIELDS,
                         ids=[f"{c.__name__}.{f}={v!r}" for c, f, v in BAD_FIELDS])
def test_every_bad_field_is_refused_by_name(cls, field, value):
    with pytest.raises(ValueError, match=rf"\b{cls.__name__}\.{field}\b"):
        cls(**{field: value})


@pytest.mark.parametrize("cls", [CEAPGConfig, CEMConfig, PAPGConfig, APGConfig, SHACConfig])
def test_every_field_has_a_validation_case(cls):
    """Every field of every config appears above, so a field added without a check (or a test) fails here; the
    defaults themselves are valid."""
    covered = {f for c, f, _ in BAD_FIELDS if c is cls}
    assert covered == {f.name for f in dataclasses.fields(cls)}
    cls()


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: CEAPGConfig(num_candidates=4, num_elites=5), r"CEAPGConfig\.num_elites must be <= num_candidates"),
        (lambda: CEAPGConfig(apg_steps=3, fitness_window=5), r"CEAPGConfig\.fitness_window must be <= apg_steps"),
        (lambda: PAPGConfig(apg_steps=3, fitness_window=5), r"PAPGConfig\.fitness_window must be <= apg_steps"),
        (lambda: CEAPGConfig(train_noise=-0.1), r"CEAPGConfig\.train_noise must be a finite number in \[0\.0, inf\)"),
        (lambda: CEAPGConfig(warmup_horizons=(100, 0)), r"CEAPGConfig\.warmup_horizons\[1\]"),
        (lambda: CEAPGConfig(warmup_horizons=(100,), warmup_iterations=0), r"CEAPGConfig\.warmup_iterations"),
        (lambda: CEAPGConfig(iterations=20, warmup_horizons=(100, 200), warmup_iterations=15),
         r"CEAPGConfig\.iterations \(20\) must cover the warm-up"),
        (lambda: CEAPGConfig(apg_steps=0, warmup_horizons=(100,)), r"CEAPGConfig\.warmup_horizons needs apg_steps"),
        (lambda: CEMConfig(apg_steps=3), r"CEMConfig\.apg_steps must be 0"),
        (lambda: CEAPGConfig(authors_normalizer=True, normalize=False),
         r"CEAPGConfig\.authors_normalizer needs normalize=True"),
        (lambda: SHACConfig(num_envs=2, short_horizon=2, critic_minibatches=5),
         r"SHACConfig\.critic_minibatches must be <= num_envs \* short_horizon \(4\)"),
        (lambda: CEAPGConfig.laptop("hopper"), r"task must be one of \['acrobot', 'cartpole', 'double_cartpole'\]"),
    ],
)
def test_cross_field_rules_name_their_fields(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_zero_apg_steps_and_the_edges_are_allowed():
    """The closed ends of the ranges are accepted: CE-APG's ``apg_steps=0`` (the plain CEM), zero noise and std,
    probabilities 0 and 1, SHAC's lam 0 and 1, no gradient clipping, no critic passes."""
    CEAPGConfig(apg_steps=0, init_std=0.0, train_noise=0.0, upright_starts=1.0, warmup_upright=0.0)
    SHACConfig(lam=0.0, target_alpha=1.0, actor_grad_norm=None, critic_grad_norm=None, critic_iterations=0)
    SHACConfig(lam=1.0, gamma=1.0, target_alpha=0.0)


def test_shac_refuses_an_objective():
    """SHAC's actor loss is its own: ``make_trainer(..., objective=f)`` is refused before anything is built."""
    with pytest.raises(ValueError, match="SHAC has its own actor loss: objective must be None"):
        SHACConfig().make_trainer(None, None, objective=lambda eps: 0.0)


def test_check_int():
    check_int("C", "n", 2, 2)
    check_int("C", "n", np.int64(2), 2)  # NumPy integers are integers
    for bad in (True, False, 2.0, "3", None, 1):
        with pytest.raises(ValueError, match=r"C\.n must be an integer >= 2, got"):
            check_int("C", "n", bad, 2)


def test_check_real_intervals():
    check_real("C", "x", 0.0, 0.0, 1.0)
    check_real("C", "x", 1.0, 0.0, 1.0)
    for bad, kw, interval in ((0.0, dict(lo_open=True), r"\(0\.0, 1\.0\]"),
                              (1.0, dict(hi_open=True), r"\[0\.0, 1\.0\)"),
                              (-1e-9, {}, r"\[0\.0, 1\.0\]"), (math.nan, {}, r"\[0\.0, 1\.0\]"),
                              (True, {}, r"\[0\.0, 1\.0\]")):
        with pytest.raises(ValueError, match=rf"C\.x must be a finite number in {interval}, got"):
            check_real("C", "x", bad, 0.0, 1.0, **kw)
    with pytest.raises(ValueError, match=r"C\.x must be a finite number in \(-inf, inf\), got inf"):
        check_real("C", "x", math.inf)
    with pytest.raises(ValueError, match=r"C\.x must be a real number, got 'a'"):
        check_real("C", "x", "a")
    check_positive("C", "x", 0.0, allow_zero=True)
    with pytest.raises(ValueError, match=r"C\.x must be a finite number in \(0\.0, inf\)"):
        check_positive("C", "x", 0.0)
    with pytest.raises(ValueError, match=r"C\.p must be a finite number in \[0\.0, 1\.0\]"):
        check_probability("C", "p", 1.01)
    check_bool("C", "b", False)
    with pytest.raises(ValueError, match=r"C\.b must be True or False, got 0"):
        check_bool("C", "b", 0)
