"""The glove pinch as the assistant measures it: its live grasp margin and closing direction.

:func:`live_margin` is the grasp margin of the pen's pinch now (the soft fingers' cones,
paper eqs. 11-20); :func:`closing_direction` is the joint-target direction that moves the two
pads straight toward each other, along the line the pinch's internal force acts on.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.glove.hand import N_JOINTS, joint_index
from ias_gym.glove.impairments import pinch_direction
from ias_gym.grasp.grasp_margin import grasp_margin
from ias_gym.sim.scene_constants import glove_pad_friction

FloatArray = NDArray[np.float64]


def live_margin(env: Any) -> float:
    """The grasp margin of the pen's pinch now [-] (NaN unless both pads touch).

    Args:
        env: an unwrapped glove env after ``reset`` or ``step``.
    """
    from ias_gym.sim.soft_finger import pinch_null_basis

    if env.contact_pass is None:
        return math.nan
    p = env.physics
    contacts = p.finger_contacts(env.contact_pass)
    W, active = p.wrench_matrix(contacts)
    if not np.all(active):
        return math.nan
    N = pinch_null_basis(W, contacts)
    if N is None:
        return math.nan
    c = p.contact_intensities(contacts)
    c_h = N @ (N.T @ c)
    return grasp_margin(c - c_h, c_h, *glove_pad_friction(), 4)


#: Joints that close the pinch along the pads' line: the index's MCP and PIP, the thumb's
#: CMC and flexion (with the thumb's coupled hinges).
CLOSING_JOINTS: dict[str, tuple[str, ...]] = {
    "index_tip": ("index_mcp", "index_pip"),
    "thumb_tip": ("thumb_cmc", "thumb_flexion"),
}


def closing_direction(env: Any) -> FloatArray:
    """``(10,)`` the joint-target direction that moves the index pad and the thumb pad
    straight toward each other (along the line between them, where the pinch's internal
    force acts: paper eq. 20), scaled to the 1-norm of
    :func:`~ias_gym.glove.impairments.pinch_direction` [rad per unit].

    Each finger's joints solve ``J dq = +-n`` in the least-squares sense with MuJoCo's site
    Jacobian (the thumb's coupled hinges folded into its flexion). Closing along the
    joints' own flexion instead (:func:`pinch_direction`) also slides the index pad along
    the pen's surface, which pushes the pen out of a firm pinch (measured:
    docs/assistance.md).

    Args:
        env: an unwrapped glove env after ``reset`` or ``step``.
    """
    import mujoco  # MuJoCo scene code

    m, d = env.model, env.data
    tips = {name: m.site(name).id for name in CLOSING_JOINTS}
    line = d.site_xpos[tips["thumb_tip"]] - d.site_xpos[tips["index_tip"]]
    n = line / max(float(np.linalg.norm(line)), 1e-9)
    out = np.zeros(N_JOINTS)
    jac = np.zeros((3, m.nv))
    flex = joint_index("thumb_flexion")
    for site, sign in (("index_tip", 1.0), ("thumb_tip", -1.0)):
        mujoco.mj_jacSite(m, d, jac, None, tips[site])
        cols = []
        for name in CLOSING_JOINTS[site]:
            col = jac[:, m.jnt_dofadr[m.joint(name).id]].copy()
            if joint_index(name) == flex:
                for j, ratio in zip(env._coupled_dofs, env._coupling, strict=True):
                    col += ratio * jac[:, j]
            cols.append(col)
        dq, *_ = np.linalg.lstsq(np.stack(cols, axis=1), sign * n, rcond=None)
        for name, v in zip(CLOSING_JOINTS[site], dq, strict=True):
            out[joint_index(name)] = v
    norm = float(np.abs(out).sum())
    return out * (float(np.abs(pinch_direction()).sum()) / norm) if norm > 0 else pinch_direction()
