"""An env's MuJoCo state set from outside: a reset's ``qpos``/``qvel`` options, a pickle's state.

The pen tasks (:class:`~ias_gym.envs.pen_hand_env.PenHandEnv`) and the glove world
(:class:`~ias_gym.envs.glove_grasp.GloveGraspEnv`) both start from an exact MuJoCo state
given as ``reset(options={"qpos": ..., "qvel": ...})`` (:func:`set_state_from_options`);
the pen tasks pickle MuJoCo's integration state (:func:`integration_state`,
:func:`restore_integration_state`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

#: What a pickled env keeps of MuJoCo's state: everything the integration needs.
INTEGRATION_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def set_state_from_options(
    model: mujoco.MjModel, data: mujoco.MjData, options: Mapping[str, Any]
) -> None:
    """Put MuJoCo's state to ``options["qpos"]`` and ``options.get("qvel", 0)``, then run a
    forward pass.

    Raises:
        ValueError: qpos/qvel of the wrong shape or not finite.
    """
    qpos = np.asarray(options["qpos"], dtype=float)
    qvel = np.asarray(options.get("qvel", np.zeros(model.nv)), dtype=float)
    if qpos.shape != (model.nq,) or qvel.shape != (model.nv,):
        raise ValueError(
            f"options qpos/qvel need shapes ({model.nq},)/({model.nv},), "
            f"got {qpos.shape}/{qvel.shape}"
        )
    if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
        raise ValueError("options qpos/qvel contain NaN or inf")
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)


def integration_state(model: mujoco.MjModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """MuJoCo's full integration state of ``data`` (``mj_getState``), a new array."""
    buf = np.empty(mujoco.mj_stateSize(model, INTEGRATION_STATE))
    mujoco.mj_getState(model, data, buf, INTEGRATION_STATE)
    return buf


def restore_integration_state(
    model: mujoco.MjModel, data: mujoco.MjData, state: NDArray[np.float64]
) -> None:
    """Set ``data`` to an :func:`integration_state` and run a forward pass."""
    mujoco.mj_setState(model, data, state, INTEGRATION_STATE)
    mujoco.mj_forward(model, data)
