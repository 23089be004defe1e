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
