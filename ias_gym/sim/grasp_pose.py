"""Placing the pen and the fingertips: a randomised but consistent initial grasp.

A reset that moves the pen must move the fingers with it, or the tips either lose the pen
or sink into it (a 1 mm overlap already means forces of several newtons). This module puts
the pen at a given pose and solves the fingers' inverse kinematics so that every tip sphere
touches the pen at a given distance along its axis, with a given penetration.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ias_gym.sim.pen_hand import PenHandPhysics, paper_to_mj, rpy_to_matrix

FloatArray = np.ndarray


def place_grasp(
    physics: PenHandPhysics,
    pen_position: ArrayLike,
    pen_rpy: ArrayLike,
    contact_x: ArrayLike,
    penetration: float = 3e-4,
    iterations: int = 30,
    tolerance: float = 1e-7,
) -> float:
    """Set the pen's pose and the fingers' joints so that the tips touch the pen.

    Args:
        physics: the pen-hand physics (its data is modified; ``mj_forward`` is run at the end).
        pen_position: pen centre [m], paper frame, relative to the nominal centre.
        pen_rpy: pen roll, pitch, yaw [rad], paper frame (as :meth:`PenHandPhysics.pen_pose`).
        contact_x: ``(k,)`` signed contact positions along the pen's axis [m] (pen frame;
            the paper's ``[-phi1, -phi2, +phi3, +phi4]`` on the four-finger hand). Each tip
            touches the side of the pen its base is on (``physics.finger_sides``); every
            finger has three joints (abd, mcp, pip), as on both registered hands.
        penetration: how far each tip sphere overlaps the pen [m].
        iterations: Gauss-Newton iterations of the inverse kinematics.
        tolerance: stop when every tip is this close to its target [m].

    Returns:
        The largest remaining tip position error [m].
    """
    m, d = physics.model, physics.data
    qa = physics._pen_qadr
    rot = rpy_to_matrix(pen_rpy)  # pen frame -> paper frame
    centre = np.asarray(pen_position, dtype=float)
    d.qpos[qa : qa + 3] = physics.origin_mj + paper_to_mj(centre)
    rot_mj = paper_to_mj(paper_to_mj(rot).T).T  # R_PAPER_TO_MJ @ rot @ R_PAPER_TO_MJ^T
    mujoco.mju_mat2Quat(d.qpos[qa + 3 : qa + 7], rot_mj.reshape(-1))
    d.qvel[:] = 0.0

    tip_radius = m.geom_size[physics._tip_geoms, 0]
    pen_radius = m.geom_size[physics._pen_geom, 0]
    offset = physics.finger_sides * (pen_radius + tip_radius - penetration)
    local = np.stack([np.asarray(contact_x, dtype=float), offset, np.zeros(len(offset))], axis=1)
    targets = physics.origin_mj + paper_to_mj(centre + local @ rot.T)

    qadr, dadr = physics.hand_qpos_ids, physics.hand_dof_ids
    lo, hi = m.jnt_range[m.dof_jntid[dadr]].T
    jac = np.zeros((3, m.nv))
    err = np.inf
    for _ in range(iterations):
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        residual = targets - d.site_xpos[physics._tip_sites]
        err = float(np.abs(residual).max())
        if err < tolerance:
            break
        for i, site in enumerate(physics._tip_sites):
            mujoco.mj_jacSite(m, d, jac, None, int(site))
            cols = dadr[3 * i : 3 * i + 3]
            J = jac[:, cols]
            step = np.linalg.solve(J.T @ J + 1e-8 * np.eye(3), J.T @ residual[i])
            q = qadr[3 * i : 3 * i + 3]
            d.qpos[q] = np.clip(d.qpos[q] + step, lo[3 * i : 3 * i + 3], hi[3 * i : 3 * i + 3])
    mujoco.mj_forward(m, d)
    return err
