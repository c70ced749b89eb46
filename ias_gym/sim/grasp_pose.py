"""Placing the pen and the fingertips: a randomised but consistent initial grasp.

A reset that moves the pen must move the fingers with it, or the tips either lose the pen
or sink into it (a 1 mm overlap already means forces of several newtons). This module puts
the pen at a given pose and solves the fingers' inverse kinematics so that every tip sphere
touches the pen at a given distance along its axis, with a given penetration.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ias_gym.sim.pen import R_PAPER_TO_MJ
from ias_gym.sim.pen_hand import GRASP_KEYFRAME, PenHandPhysics, rpy_to_matrix

FloatArray = np.ndarray


def _lapack_solve() -> Callable[[FloatArray, FloatArray], FloatArray]:
    """numpy's batched LAPACK solve without ``np.linalg.solve``'s per-call checks.

    A reset solves two batches of 3 x 3 systems; the public function's argument checks and
    error-state context cost about 40 us of a 0.3 ms reset (measured). Its gufunc is private
    to numpy, so it is used only if it exists and agrees with the public function bit for
    bit on a probe system; otherwise the public function is used.
    """
    try:
        from numpy.linalg import _umath_linalg

        def solve(a: FloatArray, b: FloatArray) -> FloatArray:
            result: FloatArray = _umath_linalg.solve(a, b, signature="dd->d")
            return result

        a = np.array([[[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]]])
        b = np.array([[[1.0], [2.0], [3.0]]])
        if np.array_equal(solve(a, b), np.linalg.solve(a, b)):
            return solve
    except Exception:  # another numpy's internals: the public function
        pass
    return np.linalg.solve


_solve = _lapack_solve()


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
            touches its side of the pen (``physics.finger_sides``); every finger has three
            driven joints (abd, mcp, pip), as on every registered hand, and a joint coupled
            to one of them (``physics.coupled``) follows it.
        penetration: how far each tip sphere overlaps the pen [m].
        iterations: Gauss-Newton iterations of the inverse kinematics.
        tolerance: stop when every tip is this close to its target [m].

    Returns:
        The largest remaining tip position error [m].
    """
    m, d = physics.model, physics.data
    c = _ik_constants(physics)
    qa = physics.pen_qpos_adr
    rot = rpy_to_matrix(pen_rpy)  # pen frame -> paper frame
    centre = np.asarray(pen_position, dtype=float)
    d.qpos[qa : qa + 3] = physics.origin_mj + R_PAPER_TO_MJ @ centre
    rot_mj = R_PAPER_TO_MJ @ rot @ R_PAPER_TO_MJ.T
    mujoco.mju_mat2Quat(d.qpos[qa + 3 : qa + 7], rot_mj.reshape(-1))
    d.qvel[:] = 0.0

    tip_radius = c.tip_radius
    pen_radius = c.pen_radius
    offset = physics.finger_sides * (pen_radius + tip_radius - penetration)
    local = np.zeros((len(offset), 3))
    local[:, 0] = contact_x
    local[:, 1] = offset
    targets = physics.origin_mj + (centre + local @ rot.T) @ R_PAPER_TO_MJ.T

    # The hand's kinematics does not depend on the pen: at the hand's keyframe posture (every
    # env reset starts there) the first iteration's tips and Jacobians are known already.
    qpos = d.qpos
    at_rest = bool((qpos.take(c.q_ids) == c.rest_qpos).all())
    err = np.inf
    for i in range(iterations):
        cached = i == 0 and at_rest
        if cached:
            tips = c.rest_tips
        else:
            mujoco.mj_kinematics(m, d)
            tips = d.site_xpos.take(c.tip_sites, axis=0)
        residual = targets - tips
        err = float(np.abs(residual).max())
        if err < tolerance:
            break
        jac_t, lhs = (c.rest_jac_t, c.rest_lhs) if cached else _finger_jacobians(c, m, d)
        # All fingers' damped Gauss-Newton steps in one batched solve (each finger is its
        # own chain); the same floating-point operations as one solve per finger.
        # (the matrices are positive definite: J^T J plus damping)
        step = _solve(lhs, jac_t @ residual[:, :, None])
        # (np.clip's values, without its call overhead; take and put: fancy indexing's
        # values in half its time)
        qpos.put(c.q_ids, np.minimum(np.maximum(qpos.take(c.q_ids) + step.ravel(), c.lo), c.hi))
        if c.coupled:  # a coupled joint follows its leader (a joint equality)
            qpos.put(c.follow_q, c.follow_ratio * qpos.take(c.leader_q))
    mujoco.mj_forward(m, d)
    return err


def _finger_jacobians(
    c: _IKConstants, m: mujoco.MjModel, d: mujoco.MjData
) -> tuple[FloatArray, FloatArray]:
    """Each fingertip's transposed position Jacobian over its own joints ``(k, n, 3)`` and
    the damped normal matrices ``J^T J + 1e-8 I`` ``(k, n, n)`` (after ``mj_kinematics``).

    ``J^T`` is kept C-contiguous: then the batched products round exactly as the former
    per-finger ``J.T @ J`` and ``J.T @ r`` of ``jac[:, cols]`` (an F-ordered copy) did, and
    the grasp stays the same bit for bit (tests/test_env_speed.py).
    """
    mujoco.mj_comPos(m, d)  # the Jacobians' cdof
    for jac, site in c.jac_rows:
        mujoco.mj_jacSite(m, d, jac, None, site)
    for leader, follower, ratio in c.coupled_columns:  # the leader moves the follower too
        leader += ratio * follower
    jac_t = np.ascontiguousarray(c.jac_buffer[c.finger_rows, :, c.finger_dofs])
    return jac_t, jac_t @ jac_t.transpose(0, 2, 1) + c.damping


class _IKConstants:
    """What the inverse kinematics reuses across resets of one physics (same model)."""

    def __init__(self, physics: PenHandPhysics) -> None:
        m = physics.model
        qadr, dadr = physics.hand_qpos_ids, physics.hand_dof_ids
        self.joints = m.dof_jntid[dadr].copy()
        if np.any(m.jnt_type[self.joints] != mujoco.mjtJoint.mjJNT_HINGE):
            raise ValueError("place_grasp's inverse kinematics needs hinge joints in the hand")
        self.tip_sites = np.asarray(physics.tip_site_ids)
        k = len(self.tip_sites)
        n = len(qadr) // k
        self.finger_rows = np.arange(k)[:, None]
        self.finger_dofs = np.asarray(dadr).reshape(k, n)
        self.jac_buffer = np.zeros((k, 3, m.nv))
        self.jac_rows = [(self.jac_buffer[f], int(site)) for f, site in enumerate(self.tip_sites)]
        self.q_ids = np.asarray(qadr)
        self.lo, self.hi = m.jnt_range[self.joints].T.copy()
        self.damping = 1e-8 * np.eye(n)
        # joints tied to a hand joint: (follower dof, leader dof, ratio), and their qpos
        self.coupled = [(dof, int(dadr[i]), r) for dof, i, r in physics.coupled]
        # their Jacobian columns as views (leader, follower, ratio), made once
        self.coupled_columns = [
            (self.jac_buffer[:, :, leader], self.jac_buffer[:, :, follower], ratio)
            for follower, leader, ratio in self.coupled
        ]
        joint_of = m.dof_jntid
        self.follow_q = np.array([m.jnt_qposadr[joint_of[f]] for f, _, _ in self.coupled], int)
        self.leader_q = np.array([m.jnt_qposadr[joint_of[a]] for _, a, _ in self.coupled], int)
        self.follow_ratio = np.array([r for _, _, r in self.coupled])
        # The hand at its keyframe posture: its tips, joint axes and anchors. Valid whenever
        # the hand's joints are there, as only they move the tips (checked: no other joint
        # or mocap body above a finger).
        for body in m.jnt_bodyid[self.joints]:
            while body != 0:
                moving = set(range(m.body_jntadr[body], m.body_jntadr[body] + m.body_jntnum[body]))
                if moving - set(self.joints.tolist()) or m.body_mocapid[body] >= 0:
                    raise ValueError("place_grasp needs a hand whose base is fixed to the world")
                body = m.body_parentid[body]
        scratch = mujoco.MjData(m)
        try:
            mujoco.mj_resetDataKeyframe(m, scratch, m.key(GRASP_KEYFRAME).id)
        except KeyError:
            pass  # no such keyframe: the model's qpos0 (the cache is then used less often)
        mujoco.mj_kinematics(m, scratch)
        self.rest_qpos = scratch.qpos[qadr].copy()
        self.rest_tips = scratch.site_xpos[self.tip_sites].copy()
        self.rest_jac_t, self.rest_lhs = _finger_jacobians(self, m, scratch)
        self.tip_radius = m.geom_size[physics.tip_geom_ids, 0].copy()
        self.pen_radius = float(m.geom_size[physics.pen_geom_id, 0])


_CONSTANTS: weakref.WeakKeyDictionary[PenHandPhysics, _IKConstants] = weakref.WeakKeyDictionary()


def _ik_constants(physics: PenHandPhysics) -> _IKConstants:
    c = _CONSTANTS.get(physics)
    if c is None:
        c = _CONSTANTS[physics] = _IKConstants(physics)
    return c
