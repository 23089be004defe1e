"""The policies' abstract base (policies/base.py): GRUPolicy, MLPPolicy and SHAC's Actor are final subclasses of
``AbstractPolicy``, which cannot be built itself; ``for_task`` sizes each for a task (the constructor's own arguments
passed on, the key ``PRNGKey(0)`` by default), ``reinit`` redraws the weights of the same architecture and dtype, and
``initial_state`` is the zero hidden state in the weights' dtype."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lagrange.tasks import Acrobot
from policies import AbstractPolicy, Actor, GRUPolicy, MLPPolicy
from tests.helpers import states_equal


def test_the_policies_share_the_abstract_base():
    with pytest.raises(TypeError, match="abstract"):
        AbstractPolicy()
    task = Acrobot.rods(trig=True)  # 6 observations, 1 action
    built = {
        GRUPolicy: (GRUPolicy.for_task(task, 8), GRUPolicy(6, 1, 8, key=jax.random.PRNGKey(0)), 6),
        MLPPolicy: (MLPPolicy.for_task(task, width=8, depth=1), MLPPolicy(6, 1, 8, 1, key=jax.random.PRNGKey(0)), 0),
        Actor: (Actor.for_task(task, units=(8,), init_log_std=-0.5),
                Actor(6, 1, (8,), init_log_std=-0.5, key=jax.random.PRNGKey(0)), 0),
    }
    for cls, (policy, by_hand, hidden) in built.items():
        assert issubclass(cls, AbstractPolicy) and getattr(cls, "__final__", False), cls
        assert states_equal(policy, by_hand), cls  # for_task: the constructor on the task's sizes, PRNGKey(0)
        h = policy.initial_state()
        assert h.shape == (hidden,) and not np.asarray(h).any() and h.dtype == jnp.float64, cls
        a, h2 = policy(jnp.ones(6), h, True)
        assert a.shape == (1,) and h2.shape == (hidden,), cls
        fresh = policy.reinit(jax.random.PRNGKey(1))
        assert type(fresh) is cls and not states_equal(fresh, policy), cls
        assert jax.tree_util.tree_structure(fresh) == jax.tree_util.tree_structure(policy), cls  # same architecture
        single = cls.for_task(task, dtype=jnp.float32)
        assert single.initial_state().dtype == single.reinit(jax.random.PRNGKey(2)).dtype == jnp.float32, cls


def test_sizes_are_checked_by_name():
    """Layer sizes and counts: integers >= 1 (NumPy's too), never a bool, a float or zero; observations of another
    size than the normaliser's are refused, naming both shapes."""
    from policies import BraxNormalizer, Critic, Normalizer

    assert GRUPolicy(np.int64(4), 1, 4, key=jax.random.PRNGKey(0)).hidden_size == 4
    refused = [
        (lambda: GRUPolicy(4, 1, 0, key=jax.random.PRNGKey(0)), r"GRUPolicy width must be an integer >= 1, got 0"),
        (lambda: MLPPolicy(4, 1, 8, -1, key=jax.random.PRNGKey(0)), r"MLPPolicy depth must be an integer >= 0"),
        (lambda: Actor(0, 1, key=jax.random.PRNGKey(0)), r"Actor obs_size must be an integer >= 1, got 0"),
        (lambda: Actor(4, 1, (8, 0), key=jax.random.PRNGKey(0)), r"Actor units\[1\] must be an integer >= 1, got 0"),
        (lambda: Actor(4, 1, 8, key=jax.random.PRNGKey(0)), r"Actor units must be a sequence of integers >= 1"),
        (lambda: Actor(4, 1, init_log_std=float("nan"), key=jax.random.PRNGKey(0)),
         r"init_log_std must be a finite number"),
        (lambda: Critic(4, (True,), key=jax.random.PRNGKey(0)), r"Critic units\[0\] must be an integer >= 1, got True"),
        (lambda: Normalizer.create(2.5), r"Normalizer size must be an integer >= 1, got 2\.5"),
        (lambda: Normalizer.create(True), r"Normalizer size must be an integer >= 1, got True"),
        (lambda: Normalizer.create(3, clip=0.0), r"Normalizer clip must be a number > 0"),
        (lambda: BraxNormalizer.create(0), r"BraxNormalizer size must be an integer >= 1, got 0"),
        (lambda: Normalizer.create(3).update(jnp.zeros((5, 4))),
         r"Normalizer: observations must have shape \(\*batch, size = 3\), got \(5, 4\)"),
        (lambda: BraxNormalizer.create(3)(jnp.zeros(4)), r"BraxNormalizer: observations must have shape"),
    ]
    for make, message in refused:
        with pytest.raises(ValueError, match=message):
            make()
