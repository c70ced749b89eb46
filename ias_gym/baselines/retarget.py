"""The retargeting baseline of skill transfer: fingertip keypoints solved to joint angles by
dex-retargeting, executed by joint position control.

What a glove-teleoperation pipeline does with a robot hand: a retargeting optimiser maps
the operator's fingertip keypoints to the robot's joint angles every frame, and the hand's
joint position servos execute them. Here the keypoints are those a glove pipeline would
give for the demonstrated object motion: each tip's place on the object, frozen at the
start of the episode and carried rigidly along ``env.reference()`` (its position plus the
rotation taking the initial axis to the reference's, as :mod:`ias_gym.baselines.kinematic`
does), pressed into the pen along the contact's initial normal (turned with the object),
:attr:`RetargetGains.depth` split between the sides above and below as the kinematic
squeeze is (on a three-finger hand the finger alone on its side presses 1.5 x the depth,
the two on the other side 0.75 x): the only grip a position-controlled hand gets is the stiffness of
its servos times that depth. No W, no internal forces, no friction cones, no weight fed
forward.

Every control step:

1. dex-retargeting 0.5.0's ``PositionOptimizer`` (``pip install 'ias-gym[retarget]'``) on
   the hand's URDF (:func:`ias_gym.sim.urdf_export.pen_hand_urdf`; the coupled distal
   joints of the Shadow and LEAP hands are URDF mimic joints, which dex-retargeting's
   ``MimicJointKinematicAdaptor`` sets from their leaders) solves the driven joint angles
   whose tips reach the keypoints, warm-started from the last solution (the measured
   angles at the first step), and the solution is clipped to the joint ranges (dex-retargeting
   allows 1e-3 rad beyond them). Its defaults regularise towards the last solution
   (``normal_delta`` 4e-3, ``ftol_abs`` 1e-5); with them the tips stopped 1.5-3.5 mm from
   reachable keypoints from a start 0.05 rad away, more than the depth itself, so
   :class:`RetargetGains` sets ``normal_delta`` 1e-6 and ``ftol_abs`` 1e-12 (a few um per
   step). Its low-pass filter is off: the reference is already smooth (Savitzky-Golay,
   docs/transfer.md);
2. a joint PD servo on the solution through the hand's inertia,
   ``tau = M(q) [omega^2 (q* - q) + 2 zeta omega (q*' - q')] + H``, i.e. ``kp = omega^2 M``
   [N m/rad] and ``kd = 2 zeta omega M`` [N m s/rad], with ``q*'`` the solutions' difference
   over one step, M the hand's joint-space inertia and H its bias forces
   (``PenHandPhysics.hand_mass_matrix``, ``hand_bias_forces``: gravity where the model does
   not compensate it, Coriolis, joint damping), clipped to the motors' ranges and normalised
   to the env's action. Why through M: the torque is held for a whole control step (10 ms),
   and the hands' finger inertias differ by 100 x (1e-5 kg m^2 on the IAS fingers, 1e-3
   with the Shadow and LEAP armatures); a free IAS finger under a constant joint gain went
   unstable at every gain tried (0.5-10 N m/rad, with or without damping), and under
   ``M(q)`` it is stable up to about omega = 100 rad/s (omega dt = 1). The chosen 130 rad/s
   is beyond that for a free IAS finger (it oscillates at the motors' limits) and stable
   only while the finger touches the pen, whose inertia adds to its own; 160 rad/s failed
   on every hand. The servo cannot be stiffer without a faster loop than the env's, and the
   pen's weight (1 N) sags it by about 2 mm on the IAS hands: what a position-controlled
   hand without force feedback does at this rate.

The depth per hand (:data:`DEPTH_BY_HAND`) and the gains were chosen on development data
only (``train/tune_retarget.py``: the first successful session of every skill class of the
first 8 persons, sorted, of population seed 3141; the table is in the CHANGELOG) and
confirmed, each the best of 0.25-4.5 mm (the Shadow hand passes none at any depth), with
references scaled into the hands' measured workspace on other development persons.
"""

from __future__ import annotations

import contextlib
import io
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.baselines.torque_policy import TorquePolicy, rotation_between, side_shares
from ias_gym.envs.pen_hand_env import FloatArray
from ias_gym.errors import InputError
from ias_gym.sim.pen import paper_to_mj
from ias_gym.sim.urdf_export import HandURDF, pen_hand_urdf

__all__ = [
    "DEFAULT_DEPTH",
    "DEPTH_BY_HAND",
    "RetargetGains",
    "RetargetPolicy",
    "build_retargeting",
    "require_retargeting",
]

#: How far each keypoint is pressed into the pen along its contact's normal [m], per hand, the
#: mean over the fingers of the press split between the sides (:func:`side_shares`): of
#: 0.25-8 mm, the one with the most successes of the transfer test (ties broken by the most
#: terms passed, as the kinematic squeeze) over the 48 glove skills of 8 development persons
#: at omega = 130 rad/s (``train/tune_retarget.py``, the table in the CHANGELOG; no depth
#: succeeds on the Shadow hand, one skill of 48 on the LEAP hand). A hand not listed gets
#: :data:`DEFAULT_DEPTH`.
DEPTH_BY_HAND: dict[str, float] = {"ias4f": 3e-3, "ias3f": 4.5e-3, "shadow": 1e-3, "leap": 2.5e-4}
DEFAULT_DEPTH = 1e-3

#: The message when dex-retargeting (or a package it imports) is missing.
MISSING = (
    "the retargeting baseline needs dex-retargeting ({}); install it with "
    "pip install 'ias-gym[retarget]'"
)


@dataclass(frozen=True)
class RetargetGains:
    """Gains of the retargeting baseline (units in the comments)."""

    # the servo's natural frequency [rad/s]: kp = omega^2 M(q) [N m/rad]; of 70, 100, 130
    # and 160 the one with the most successes on development persons (160 was unstable on
    # every hand; train/tune_retarget.py)
    omega: float = 130.0
    # its damping ratio [-]: kd = 2 zeta omega M(q) [N m s/rad]
    zeta: float = 1.0
    # the keypoints' press into the pen [m]; None: the hand's own from DEPTH_BY_HAND
    depth: float | None = None
    # add the hand's bias forces H [N m] to the servo's torque
    bias: bool = True
    # dex-retargeting's PositionOptimizer: the weight of its pull towards the last
    # solution [-] and nlopt's absolute tolerance on its objective [m^2 / m]
    normal_delta: float = 1e-6
    ftol_abs: float = 1e-12


#: Retargeting objects built per URDF and optimiser settings (one per hand in a process:
#: building parses the URDF with pinocchio).
_BUILT: dict[tuple[str, float, float], Any] = {}


def require_retargeting() -> None:
    """Check that dex-retargeting and what it imports (pinocchio, nlopt, torch, six) load.

    Raises:
        InputError: one of them is missing; the message names ``ias-gym[retarget]``.
    """
    try:
        import dex_retargeting.optimizer  # torch and nlopt
        import dex_retargeting.retargeting_config  # noqa: F401  (pinocchio, six)
    except ImportError as exc:
        missing = f"{exc.name or exc} is missing"
        if exc.name == "torch":  # imported, not declared, by dex-retargeting: not in the extra
            missing += "; the extra does not bring it: install the CPU torch as `make setup` does"
        raise InputError(MISSING.format(missing)) from None


def build_retargeting(urdf: HandURDF, normal_delta: float = 1e-6, ftol_abs: float = 1e-12) -> Any:
    """dex-retargeting's ``SeqRetargeting`` with a ``PositionOptimizer`` for a hand's URDF:
    the driven joints solved, the tip links as the targets, joint limits on, no low-pass
    filter (cached per URDF and settings).

    Args:
        urdf: from :func:`~ias_gym.sim.urdf_export.pen_hand_urdf`.
        normal_delta: the optimiser's pull towards the last solution [-].
        ftol_abs: nlopt's absolute tolerance on the objective.

    Raises:
        InputError: dex-retargeting, or a package it imports (torch, six, nlopt,
            pinocchio), is not installed; the message names ``ias-gym[retarget]``.
    """
    key = (urdf.text, normal_delta, ftol_abs)
    if key in _BUILT:
        return _BUILT[key]
    require_retargeting()
    from dex_retargeting.retargeting_config import RetargetingConfig

    with tempfile.TemporaryDirectory(prefix="ias-gym-urdf-") as tmp:
        path = urdf.write(Path(tmp) / "hand.urdf")
        config = RetargetingConfig(
            type="position",
            urdf_path=str(path),
            target_link_names=list(urdf.tips),
            target_link_human_indices=np.arange(len(urdf.tips)),
            target_joint_names=list(urdf.joints),
            normal_delta=normal_delta,
            low_pass_alpha=-1.0,  # no filter
        )
        # build() writes its own copy of the URDF into a new temporary folder: inside ours
        saved, tempfile.tempdir = tempfile.tempdir, tmp
        try:
            retargeting = config.build()
        finally:
            tempfile.tempdir = saved
    retargeting.optimizer.opt.set_ftol_abs(ftol_abs)
    _BUILT[key] = retargeting
    return retargeting


class RetargetPolicy(TorquePolicy):
    """``predict(obs) -> (action, None)``: keypoints retargeted to joint angles, joint PD.

    Privileged like the kinematic baseline: it reads the unwrapped env's reference, tip
    positions, contact normals and joint state, and acts only through the env's action
    (normalised torques).

    Args:
        env: an ``IAS-Pen*`` environment with a ``reference()`` (wrappers are looked through).
        gains: servo gains, depth and optimiser settings.

    Attributes:
        failures: steps whose optimisation failed (nlopt's round-off stop, or an error
            dex-retargeting caught and printed); the last solution was kept for them.
        residual: the largest distance of a solved tip from its keypoint at the last step
            [m] (dex-retargeting's forward kinematics, before the clip to the ranges).

    Raises:
        InputError: dex-retargeting is not installed (``pip install 'ias-gym[retarget]'``).
    """

    def __init__(self, env: gym.Env[Any, Any], gains: RetargetGains | None = None) -> None:
        super().__init__(env, "retargeting baseline")
        self.gains = gains or RetargetGains()
        p, m = self.env.physics, self.env.model
        self.urdf = pen_hand_urdf(p, self.env.config.hand)
        self.retargeting = build_retargeting(
            self.urdf, self.gains.normal_delta, self.gains.ftol_abs
        )
        names = list(self.retargeting.joint_names)  # pinocchio's order, mimic joints too
        self._pin_of_hand = np.array([names.index(j) for j in self.urdf.joints])
        self._target_of_hand = np.array(
            [list(self.retargeting.optimizer.target_joint_names).index(j) for j in self.urdf.joints]
        )
        self._lower = m.jnt_range[m.dof_jntid[p.hand_dof_ids], 0].copy()
        self._upper = m.jnt_range[m.dof_jntid[p.hand_dof_ids], 1].copy()
        self._tau_max = self.env._ctrl_max.copy()  # [N m]: the env's motors act as torques
        self.failures = 0
        self.residual = 0.0
        self.reset()

    def reset(self) -> None:
        """Forget the attachment and the last solution; the next call starts anew."""
        self._attached: FloatArray | None = None
        self._axis0: FloatArray | None = None
        self._solution: FloatArray | None = None  # the driven joints, the hand's order
        self.failures = 0

    def keypoints(self) -> FloatArray:
        """The tips' targets now [m], ``(k, 3)``, paper frame (origin: the nominal centre)."""
        env, p = self.env, self.env.physics
        ref = env.reference()
        if self._attached is None:
            depth = self.gains.depth
            if depth is None:
                depth = DEPTH_BY_HAND.get(env.config.hand, DEFAULT_DEPTH)
            normals = p.fingertip_contacts().frames[:, 0]  # into the pen
            # the same press from above and below (the kinematic squeeze's split)
            press = depth * side_shares(normals)
            self._attached = p.tip_positions() - ref.position + press[:, None] * normals
            self._axis0 = ref.axis.copy()
        assert self._axis0 is not None
        R = rotation_between(self._axis0, ref.axis)
        out: FloatArray = ref.position + self._attached @ R.T
        return out

    def solve(self) -> FloatArray:
        """The driven joint angles [rad] whose tips reach :meth:`keypoints` (the hand's order)."""
        p = self.env.physics
        targets = paper_to_mj(self.keypoints()) + p.origin_mj  # MuJoCo's world: the URDF's
        rt = self.retargeting
        last = np.asarray(rt.last_qpos, dtype=np.float32).copy()
        last[self._target_of_hand] = p.hand_qpos() if self._solution is None else self._solution
        rt.last_qpos = last
        with contextlib.redirect_stdout(io.StringIO()) as printed:  # it prints its errors
            try:
                robot_qpos = np.asarray(rt.retarget(targets), dtype=float)
            except Exception:  # nlopt.RoundoffLimited derives from Exception only
                robot_qpos = np.asarray(rt.get_qpos(), dtype=float)
                if rt.optimizer.adaptor is not None:  # the coupled joints from their leaders
                    robot_qpos = rt.optimizer.adaptor.forward_qpos(robot_qpos)
                self.failures += 1
        if printed.getvalue():
            self.failures += 1
        qpos = np.clip(robot_qpos[self._pin_of_hand], self._lower, self._upper)
        robot = rt.optimizer.robot
        robot.compute_forward_kinematics(robot_qpos)
        reached = np.array(
            [robot.get_link_pose(i)[:3, 3] for i in rt.optimizer.target_link_indices]
        )
        self.residual = float(np.max(np.linalg.norm(reached - targets, axis=1)))
        return qpos

    def torques(self) -> FloatArray:
        """Joint torques [N m] for the env's current state and reference."""
        p = self.env.physics
        previous = self._solution
        q_star = self.solve()
        self._solution = q_star
        rate = np.zeros_like(q_star) if previous is None else (q_star - previous) / self.env.dt
        w, z = self.gains.omega, self.gains.zeta
        accel = w * w * (q_star - p.hand_qpos()) + 2.0 * z * w * (rate - p.hand_qvel())
        tau: FloatArray = p.hand_mass_matrix() @ accel
        if self.gains.bias:
            tau = tau + p.hand_bias_forces()
        out: FloatArray = np.clip(tau, -self._tau_max, self._tau_max)
        return out
