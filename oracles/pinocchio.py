"""A Pinocchio model of a planar chain or tree, built independently from its parameters: the reference of
``tests/lagrange/planar/test_trees.py`` (CRBA, RNEA and ABA on a branched tree) and of ``benchmarks/throughput.py``
(ABA and its derivatives timed, trajectories compared). Needs Pinocchio (``pip install -e ".[test]"``)."""

from __future__ import annotations

import numpy as np

from lagrange.chain import Chain
from lagrange.planar.lower import lower


def pinocchio_model(chain: Chain):
    """A Pinocchio model of ``chain``: each joint a revolute about y (MuJoCo's and Pinocchio's +y is our -y:
    ``q_pin = -sense q``) or a prismatic joint along its axis in the x-z plane, placed at its attach point and turned by
    its offset."""
    import pinocchio as pin

    chain = lower(chain)  # the planar parameters: masses, lengths, centres of mass, frame offsets
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -float(chain.gravity)])
    attach = dict(zip(chain.attached, np.asarray(chain.attach) if chain.attach is not None else []))
    ids = []
    normal = np.zeros(chain.n) if chain.com_normal is None else np.asarray(chain.com_normal)
    for i, joint in enumerate(chain.joints):
        p = chain.parents[i]
        parent = 0 if p < 0 else ids[p]
        x, z = attach[i] if i in attach else (0.0, -float(chain.length[p]) if p >= 0 else 0.0)
        turn = chain.offsets[i]  # about -y
        R = np.array([[np.cos(turn), 0.0, np.sin(turn)], [0.0, 1.0, 0.0], [-np.sin(turn), 0.0, np.cos(turn)]])
        placement = pin.SE3(R, np.array([x, 0.0, z]))
        if joint == "revolute":
            jm = pin.JointModelRY()
        else:
            a = chain.axes[i] - turn  # in this body's (turned) frame
            jm = pin.JointModelPrismaticUnaligned(np.array([np.cos(a), 0.0, np.sin(a)]))
        jid = model.addJoint(parent, jm, placement, f"q{i}")
        I = float(chain.inertia[i])
        model.appendBodyToJoint(jid, pin.Inertia(float(chain.mass[i]), np.array([normal[i], 0.0, -float(chain.com[i])]),
                                                 np.diag([I, I, I])), pin.SE3.Identity())
        ids.append(jid)
    return model
