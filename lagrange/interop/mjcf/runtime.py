"""Running MuJoCo on a model: compile it, step it (:func:`mujoco_rollout`), and name the lagrange integrator that
reproduces its ``mj_step`` (:func:`solver_of`). MuJoCo is imported when first needed (``pip install -e ".[mjcf]"``).
"""

from __future__ import annotations

import numpy as np

def import_mujoco():
    """Import MuJoCo, or say how to install it.

    Returns:
        The ``mujoco`` module.

    Raises:
        ImportError: without MuJoCo, naming ``pip install -e ".[mjcf]"``.
    """
    try:
        import mujoco
    except ImportError as err:  # pragma: no cover - the test extra installs it
        raise ImportError(
            "from_mjcf reads models with MuJoCo's own compiler; install it with pip install -e \".[mjcf]\""
        ) from err
    return mujoco


def compile_model(source):
    """A model compiled by MuJoCo.

    Args:
        source: a path to an MJCF file, an MJCF string (starting with ``<``), or a compiled ``mujoco.MjModel``
            (returned as it is).

    Returns:
        The ``mujoco.MjModel``.

    Raises:
        FileNotFoundError: for a path with no file.
        TypeError: for anything else.
    """
    mujoco = import_mujoco()
    if isinstance(source, mujoco.MjModel):
        return source
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return mujoco.MjModel.from_xml_string(source)
    import os

    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"from_mjcf: no MJCF file at {path!r} "
                                    "(pass a path, an XML string or a mujoco.MjModel)")
        return mujoco.MjModel.from_xml_path(path)
    raise TypeError("from_mjcf: source must be a path, an MJCF string or a mujoco.MjModel, "
                    f"got {type(source).__name__}")


def mujoco_rollout(source, q0, qd0, controls):
    """MuJoCo's own ``mj_step`` rollout of a model, for cross-checks and for data to identify a tree from.

    Args:
        source: a path, an MJCF string or a compiled ``mujoco.MjModel`` (:func:`compile_model`).
        q0: the initial ``qpos``, shape ``(nq,)``.
        qd0: the initial ``qvel``, shape ``(nv,)``.
        controls: the ``ctrl`` of each step, shape ``(T, nu)``.

    Returns:
        ``(states, met)``: the states, shape ``(T + 1, nq + nv)``, as rows ``(qpos, qvel)``; and whether MuJoCo met a
        constraint on the way (a joint limit or a contact, where a tree loaded with ``"ignore"`` by
        :func:`from_mjcf` has none). The data of :func:`optim.identify.identify`.
    """
    mujoco = import_mujoco()
    model = compile_model(source)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q0, qd0
    controls = np.asarray(controls, dtype=float).reshape(-1, model.nu)
    states, met = [np.concatenate([data.qpos, data.qvel])], False
    for u in controls:
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
        met |= data.nefc > 0
        states.append(np.concatenate([data.qpos, data.qvel]))
    return np.array(states), bool(met)


def solver_of(source):
    """The :mod:`lagrange.integrate.solvers` integrator that reproduces a model's ``mj_step``, and its time step.

    MuJoCo's ``Euler`` (damping implicit, as ``eulerdamp`` leaves it) is :class:`lagrange.SemiImplicitEuler`; its
    ``RK4`` is :class:`lagrange.RK4`.

    Args:
        source: a path, an MJCF string or a compiled ``mujoco.MjModel`` (:func:`compile_model`).

    Returns:
        ``(solver, timestep)``: the solver instance and the model's ``option/timestep`` [s].

    Raises:
        NotImplementedError: for ``implicit``, ``implicitfast``, and ``Euler`` with ``eulerdamp`` disabled on a
            damped model, which have no counterpart.
    """
    from lagrange.integrate.solvers import RK4, SemiImplicitEuler

    mujoco = import_mujoco()
    model = compile_model(source)
    kind = mujoco.mjtIntegrator(model.opt.integrator)
    dt = float(model.opt.timestep)
    if kind == mujoco.mjtIntegrator.mjINT_RK4:
        return RK4(), dt
    if kind == mujoco.mjtIntegrator.mjINT_EULER:
        if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP and np.any(model.dof_damping != 0):
            raise NotImplementedError("solver_of: Euler with eulerdamp disabled treats damping explicitly, which no "
                                      "lagrange solver does; enable eulerdamp or use RK4")
        return SemiImplicitEuler(), dt
    raise NotImplementedError(f"solver_of: MuJoCo's {kind.name[6:]} integrator has no lagrange counterpart; use Euler "
                              "(lagrange.SemiImplicitEuler) or RK4 (lagrange.RK4)")
