"""IAS-GloveGrasp-v0: the sensor glove drives a human hand that pinches and lifts the pen.

Paper 2.1-2.4 (the skill-acquisition loop of Figs. 1-2): every control step the glove is read
(readings Ψ [rad]), the person's calibration maps them to joint angles Θ = f(Ψ) (eq. (1)),
and these become the position targets of the hand model's actuators, plus the agent's
offsets. The contact forces of the pen on the index and thumb pads are mapped to torques on
the glove's actuated joints, ``tau = J^T f`` (force display), observed and written back to
the glove (``device.write_feedback``).

The scene (``scene_glove.xml`` = ``human_hand.xml`` + ``pen.xml`` + a support) is built per
person by :func:`~ias_gym.sim.glove_scene.load_glove_scene`; the scripted operator is
:mod:`ias_gym.glove.operator`'s, the cached calibration :mod:`ias_gym.glove.profile_cache`'s.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ias_gym.envs.glove_grasp_config import GloveGraspConfig
from ias_gym.envs.glove_grasp_rewards import PLACE_TOLERANCE, REWARD_TERMS, reward_terms
from ias_gym.envs.glove_readings import default_glove, read_theta
from ias_gym.envs.glove_world import OBSERVATION, OBSERVATION_SIZE, GloveWorldEnv
from ias_gym.envs.mujoco_state import set_state_from_options
from ias_gym.errors import InputError
from ias_gym.glove.calibration import Calibration
from ias_gym.glove.closed_loop import ClosedLoopOperator, pen_tilt
from ias_gym.glove.device import GloveDevice, WorldView
from ias_gym.glove.hand import JOINT_HIGH, JOINT_LOW, JOINT_NAMES, PersonParams
from ias_gym.glove.operator import FromPreShape
from ias_gym.glove.profile_cache import default_calibration
from ias_gym.glove.skills import (
    SkillStyle,
    skill_motion_time,
    skill_object_target,
    skill_start_time,
)
from ias_gym.sim.glove_scene import INDEX_GEOMS, THUMB_GEOMS, load_glove_scene
from ias_gym.sim.glove_scene import scene_operator as pen_operator  # its older name here

FloatArray = NDArray[np.float64]

#: Names that moved to the layers below and are still imported from here.
__all__ = [
    "INDEX_GEOMS",
    "NONFINITE_THETA_FAULT",
    "THUMB_GEOMS",
    "FromPreShape",
    "GloveGraspEnv",
    "default_calibration",
    "load_glove_scene",
    "pen_operator",
]


#: Info keys of the person's intended object motion (:func:`skill_object_target`): the pen's
#: height above its start [m] and its tilt [rad] as their plan means them now. A recorded
#: session keeps them, so it carries the object trajectory it was meant to follow.
TARGET_INFO: tuple[str, str] = ("target_height", "target_tilt")
#: ``info["fault"]`` when the calibration turns the glove's readings into NaN or inf (a
#: broken calibration): the step keeps the last finite targets and ends the episode.
NONFINITE_THETA_FAULT = "calibration gave non-finite joint angles (check the glove profile)"


class GloveGraspEnv(GloveWorldEnv):
    """The glove-driven human hand pinches the pen and lifts it (``IAS-GloveGrasp-v0``).

    ## Description
    Every step reads the glove (Ψ [rad]), calibrates it (Θ = f(Ψ) [rad]), low-passes it
    (``filter_tau``) and sets the hand's position targets to Θ + ``action_scale`` x action,
    clipped to the joint ranges. With zero action the env is pure teleoperation; the
    default glove is the simulated person ``person_id`` running the pen pinch
    (:func:`~ias_gym.glove.operator.pen_operator`, a
    :class:`~ias_gym.glove.device.ReachPinchLift`) from its pre-shape (:class:`FromPreShape`):
    close the pinch (0.7 s), hold (0.5 s), lift by extending the wrist (1 s), hold.
    With ``skill=NAME`` (one of :data:`ias_gym.glove.skills.SKILLS`) the person performs
    that skill after a quicker pinch-lift (close 0.7 s, hold 0.3 s, lift 0.7 s, a 4 N
    pinch), in their own style (:class:`~ias_gym.glove.skills.SkillStyle`, from the id);
    its own motion starts at :attr:`skill_start`.

    Force display: the contact forces of the pen on the index and thumb geoms, f [N], give
    ``tau = J^T f`` [N m] on the actuated joints (MuJoCo Jacobians at the contact points; the
    thumb's coupled MCP/IP hinges fold into thumb_flexion), in the observation, in
    ``info["feedback_torques"]`` and written to the glove (``write_feedback``, saturated there).
    The same pass over MuJoCo's contacts resolves each finger's contacts for the skill model
    (:attr:`contact_pass`, read by
    :class:`~ias_gym.skills.glove_session.GloveSkillModelRecorder`).

    ## Action Space
    ``Box(-1, 1, (10,))``: offsets of the 10 joint targets in the order of
    :data:`~ias_gym.glove.hand.JOINT_NAMES`, times ``action_scale`` [rad]. Values outside
    [-1, 1] are clipped; NaN or inf raise ``ValueError``.

    ## Observation Space
    ``(39,)`` float64. By name: ``env.unwrapped.observation_layout[name]`` is the part's slice
    (:data:`~ias_gym.envs.glove_world.OBSERVATION_PARTS` in order):

    | name | size | content |
    |---|---|---|
    | ``joint_angles`` | 10 | hand joint angles [rad], ``JOINT_NAMES`` order |
    | ``joint_velocities`` | 10 | their velocities [rad/s] |
    | ``pen_position`` | 3 | pen centre relative to its start, world frame [m] |
    | ``pen_quat`` | 4 | pen orientation quaternion (w, x, y, z), world frame |
    | ``pen_velocity`` | 3 | pen centre velocity, world frame [m/s] |
    | ``pen_omega`` | 3 | pen angular velocity, world frame [rad/s] |
    | ``feedback_torques`` | 5 | force display on ``ACTUATED_JOINTS`` [N m] |
    | ``time`` | 1 | episode time [s] |

    ## Rewards
    The sum of four terms, each in ``info["reward_<name>"]``: ``pinch = contact_weight``
    while both index and thumb touch the pen (else 0), ``effort = -effort_weight *
    mean(action^2)``, and two that follow the task. Without a skill, ``lift = lift_weight *
    clip(dz / lift_height, 0, 1)`` (dz: pen height gain [m]) and ``track = 0``. With a
    skill, both follow its intended object motion
    (:func:`~ias_gym.glove.skills.skill_object_target` with the person's style: the pen's
    height and tilt their plan means at this time):
    ``lift = lift_weight * k(dz - height, HEIGHT_TOLERANCE)`` and
    ``track = track_weight * k(tilt - tilt_0 - target tilt, TILT_TOLERANCE)`` with
    ``k(e, w) = 1 / (1 + (e / w)^2)`` and tilt_0 the pen's tilt at reset: holding the pen
    still earns less in a tilt, a slow see-saw or a place than doing it. (The glove chain,
    its low-pass and the hand's servos, lags a fast see-saw so much that the person alone
    earns no more there than holding still: an agent acting on the hand can lead it.)

    ## Starting State
    Every reset opens the glove anew (``glove_factory`` with a seed drawn from the env's
    ``np_random``) and reads it once: the hand starts at rest at the calibrated Θ of that
    reading (clipped to the joint ranges), the pen at rest at its start on the support, and
    the force display of that state is written to the glove. ``reset(options={"qpos": ...,
    "qvel": ...})`` then sets that exact MuJoCo state (e.g. a perturbed start).

    ## Episode End
    Terminated when the pen falls ``drop_height`` below its start or leaves
    ``max_distance`` of it; truncated at ``duration`` (also by the registered
    ``max_episode_steps``), when the glove reports a fault (``info["fault"]`` says which,
    e.g. a CAN watchdog trip, or :data:`NONFINITE_THETA_FAULT` when the calibration turns
    readings into NaN or inf, whose targets never reach MuJoCo: the last finite ones are
    kept; ``""`` otherwise), or when the simulation diverges (``info["sim_unstable"]``:
    MuJoCo raised a warning, e.g. a huge acceleration, or the state is not finite; the
    state is then put back to the start, not terminated). ``info["is_success"]``: pen >=
    ``lift_height`` above its start and touching neither the support nor the floor; for
    the skill ``lift_place``: lifted so before, and now back within
    :data:`~ias_gym.envs.glove_grasp_rewards.PLACE_TOLERANCE` of its start with both fingers
    holding it.
    ``info["operator_failure"]`` says why the simulated person failed on their side (``""``:
    they did not; e.g. ``"dropped the pen"``: they saw it fall and gave up).
    ``info["skill_phase"]``: 0 before the skill's own motion (or without a skill), 1 during
    it, 2 after; ``info["target_height"]`` [m] and ``info["target_tilt"]`` [rad]: the
    intended object motion the reward follows (:data:`TARGET_INFO`). A recorded session keeps
    them, so its timeline and its intended object trajectory travel with it
    (:func:`~ias_gym.skills.glove_session.motion_window`,
    :func:`~ias_gym.skills.glove_session.object_target`).

    ## Arguments
    ``render_mode`` (``None`` or ``"rgb_array"``), ``person``, ``calibration`` and
    ``glove_factory`` (see :meth:`__init__`), and the fields of
    :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig`
    (defaults in brackets): ``person_id`` [``"p1"``]: the simulated person wearing the
    glove, any valid id (:func:`~ias_gym.glove.ids.check_id`; a new id's calibration is
    trained once, seconds, and cached); ``skill`` [None]: the skill performed after the
    pinch-lift (None: the pinch-lift alone); ``operator`` [``"closed_loop"``]: the
    simulated person acts on what they see and feel
    (:class:`~ias_gym.glove.closed_loop.ClosedLoopOperator`), or ``"script"``: the open-loop
    plan alone, as before; ``control_dt`` [0.01 s]: one step = one glove read, a multiple
    of 1 ms;
    ``duration`` [4.0 s]; ``action_scale`` [0.2 rad]: joint offset of a full action;
    ``filter_tau`` [0.05 s, 0: off]: the low-pass on Θ; ``lift_height`` [0.03 m]: success;
    ``drop_height`` [0.05 m] and ``max_distance`` [0.15 m]: termination; ``lift_weight``
    [1.0], ``track_weight`` [1.0], ``contact_weight`` [0.5], ``effort_weight`` [0.1]: reward
    weights [-].

    ## Version History
    - v0: first version; the ``skill`` argument and soft-finger pads in the skill model
      added later; then the closed-loop person (``operator``, the default; ``"script"``
      keeps the open-loop plan), persons drawn from the documented population, a reward
      that follows the skill, and ``info["operator_failure"]``.

    Attributes:
        model, data: the compiled scene of the person's hand and its state.
        physics: :class:`~ias_gym.sim.glove_contacts.GlovePenPhysics` of the scene (index,
            thumb).
        contact_pass: the pen's contacts of the last ``reset`` or ``step`` (``None`` before).
        skill_start: episode time [s] where the skill's own motion begins
            (:func:`~ias_gym.glove.skills.skill_start_time`); ``None`` without a skill.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 100}  # noqa: RUF012

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        person: PersonParams | None = None,
        calibration: Calibration | None = None,
        glove_factory: Callable[[int], GloveDevice] | None = None,
        **config: Any,
    ) -> None:
        """Build the env.

        Args:
            render_mode: ``None`` or ``"rgb_array"``.
            person: the hand's owner (default: ``PersonParams.sample(config.person_id)``).
            calibration: Θ = f(Ψ) of that person (default:
                :func:`~ias_gym.glove.profile_cache.default_calibration`).
            glove_factory: ``seed -> GloveDevice`` called at every reset (a stream of
                readings per episode). Default: a
                :class:`~ias_gym.glove.device.SimulatedGlove` (seeded noise) on the person
                running :class:`~ias_gym.glove.operator.FromPreShape` of
                :class:`~ias_gym.glove.device.ReachPinchLift`.
            **config: fields of :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig`
                to override.
        """
        fields = {f.name for f in dataclasses.fields(GloveGraspConfig)}
        unknown = sorted(set(config) - fields)
        if unknown:
            raise TypeError(f"unknown config {unknown}; known: {sorted(fields)}")
        self.config = GloveGraspConfig(**config)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(
                f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}"
                + ("; there is no window viewer, use rgb_array" if render_mode == "human" else "")
            )
        self.render_mode = render_mode
        self.person = person if person is not None else PersonParams.sample(self.config.person_id)
        #: How the person moves (the skill reward follows their intended timing).
        self.style = SkillStyle.sample(self.person.person_id)
        self.calibration = (
            calibration if calibration is not None else default_calibration(self.person)
        )
        super().__init__(self.person, self.config.control_dt)  # the scene, the force display
        #: The simulated person of the episode when the default glove is used (None else).
        self.operator: ClosedLoopOperator | None = None
        if glove_factory is None:
            glove_factory = self._default_glove
        self.glove_factory = glove_factory
        self.glove: GloveDevice | None = None
        #: Episode time [s] where the skill's own motion begins (None: no skill).
        self.skill_start: float | None = (
            None if self.config.skill is None else skill_start_time(self.config.skill, self.person)
        )
        #: Episode time [s] where the skill's own motion ends (None: no skill).
        self.skill_end: float | None = (
            None
            if self.skill_start is None or self.config.skill is None
            else self.skill_start + skill_motion_time(self.config.skill, self.style.speed)
        )
        self.max_steps = round(self.config.duration / self.config.control_dt)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.config.control_dt)}

        self._tilt_start = 0.0  # the pen's tilt at reset [rad]
        self._unstable = False
        self._fault = ""  # latched for the episode: a broken calibration stays broken

        self.action_space = spaces.Box(-1.0, 1.0, shape=(len(JOINT_NAMES),), dtype=np.float32)
        self.observation_space = spaces.Box(
            -np.inf, np.inf, shape=(OBSERVATION_SIZE,), dtype=np.float64
        )
        #: Names to slices of the observation (:data:`~ias_gym.envs.glove_world.OBSERVATION`;
        #: subclasses extend it).
        self.observation_layout = dict(OBSERVATION)
        cfg = self.config
        self._alpha = cfg.control_dt / (cfg.filter_tau + cfg.control_dt)
        self._theta = np.zeros(len(JOINT_NAMES))
        self._touch = (False, False)
        self._pinch_force = 0.0
        self._lifted = False  # the pen was lifted off its support in this episode

    # ------------------------------------------------------------------ glove
    def _default_glove(self, seed: int) -> GloveDevice:
        """The simulated person of ``config.person_id`` doing the pen's pinch-lift (and the
        skill) on a :class:`~ias_gym.glove.device.SimulatedGlove`: in the loop or by the
        open script (:func:`~ias_gym.envs.glove_readings.default_glove`)."""
        cfg = self.config
        glove, operator = default_glove(self.model, self.person, cfg.skill, cfg.operator, seed)
        if operator is not None:
            self.operator = operator
        return glove

    def _show(self) -> None:
        """Show the glove's wearer the pen as it is now (the virtual world's display)."""
        assert self.glove is not None
        d = self.data
        self.glove.show(
            WorldView(
                time=self._steps * self.config.control_dt,
                pen_position=d.xpos[self._pen_body] - self._pen_start,
                pen_quat=d.xquat[self._pen_body].copy(),
            )
        )

    def _open_glove(self, seed: int) -> GloveDevice:
        """The glove of a new episode: a fresh device from ``glove_factory`` (the previous
        one closed), armed with :meth:`~GloveDevice.enable`."""
        if self.glove is not None:
            self.glove.close()
        glove = self.glove_factory(seed)
        glove.enable()
        return glove

    def _read_theta(self, fallback: FloatArray) -> tuple[FloatArray, bool]:
        """Θ [rad] of a new reading and whether it is finite
        (:func:`~ias_gym.envs.glove_readings.read_theta`; ``fallback``: the last finite)."""
        assert self.glove is not None
        return read_theta(self.glove, self.calibration, fallback)

    # ------------------------------------------------------------------ task
    def _success(self, dz: float, rest: bool) -> bool:
        """The pen is lifted (``lift_height``, off the support); ``lift_place``: it was lifted
        and now rests within ``PLACE_TOLERANCE`` of its start, still pinched by both."""
        lifted = dz >= self.config.lift_height and not rest
        self._lifted = self._lifted or lifted
        if self.config.skill == "lift_place":
            return self._lifted and abs(dz) <= PLACE_TOLERANCE and all(self._touch)
        return lifted

    def _info(self, terms: dict[str, float], rest: bool, fault: str) -> dict[str, Any]:
        dz = float(self.data.xpos[self._pen_body][2] - self._pen_start[2])
        return {
            "fault": fault,
            "sim_unstable": self._unstable,
            **{f"reward_{k}": v for k, v in terms.items()},
            "is_success": self._success(dz, rest),
            "pen_height": dz,
            "feedback_torques": self._feedback.copy(),
            "pinch_force": self._pinch_force,
            "index_contact": self._touch[0],
            "thumb_contact": self._touch[1],
            "operator_failure": self._operator_failure(),
            "skill_phase": self._skill_phase(),
            **dict(zip(TARGET_INFO, self._target(), strict=True)),
        }

    def _skill_phase(self) -> int:
        """Where the skill is (stored with every recorded session, so that it describes
        itself): 0 before its own motion (or without a skill), 1 during it, 2 after."""
        if self.skill_start is None or self.skill_end is None:
            return 0
        t = self._steps * self.config.control_dt
        return 0 if t < self.skill_start else (1 if t < self.skill_end else 2)

    def _operator_failure(self) -> str:
        """Why the simulated person could not do the skill (``""``: nothing on their side)."""
        op = self.operator
        if op is None:
            return ""
        return op.infeasible or op.failure

    def _target(self) -> tuple[float, float]:
        """The person's intended (pen height [m], tilt [rad]) now
        (:func:`~ias_gym.glove.skills.skill_object_target`); the pinch-lift's without a skill."""
        return skill_object_target(
            self.config.skill, self._steps * self.config.control_dt, self.style
        )

    def _rewards(self, action: FloatArray) -> dict[str, float]:
        dz = float(self.data.xpos[self._pen_body][2] - self._pen_start[2])
        errors = None
        if self.config.skill is not None:  # the skill's intended motion, as this person means it
            height, target = self._target()
            tilt = pen_tilt(self.data.xquat[self._pen_body]) - self._tilt_start
            errors = (dz - height, tilt - target)
        return reward_terms(self.config, action, dz, all(self._touch), errors)

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """The task's measures of a finished episode, from its last ``info``: the pen's
        final height above its start [m] and the pads' normal force on it [N]."""
        return {"pen_height": float(info["pen_height"]), "pinch_force": float(info["pinch_force"])}

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Start an episode (see the class docstring, "Starting State").

        Args:
            seed: seeds ``self.np_random`` (the glove's noise seed is drawn from it).
            options: ``{"qpos": ..., "qvel": ...}`` starts from that exact MuJoCo state
                after the glove's first reading (e.g. a perturbed start,
                ``tests/closed_loop.py``); default: the hand at the reading, the pen at rest.

        Raises:
            ValueError: ``options`` qpos/qvel of the wrong shape or not finite.
        """
        super().reset(seed=seed)
        self.operator = None
        self.glove = self._open_glove(int(self.np_random.integers(2**31)))
        rest_pose = np.clip(np.zeros(len(JOINT_NAMES)), JOINT_LOW, JOINT_HIGH)
        theta, ok = self._read_theta(rest_pose)
        self._theta = theta
        self._fault = "" if ok else NONFINITE_THETA_FAULT  # the first step ends the episode
        self._unstable = False
        self._place_hand(theta)
        if options and "qpos" in options:
            set_state_from_options(self.model, self.data, options)
        self._lifted = False
        self._pen_start = self.data.xpos[self._pen_body].copy()
        self._tilt_start = pen_tilt(self.data.xquat[self._pen_body])
        self._steps = 0
        self._feedback, self._touch, self._pinch_force, rest = self._force_display()
        self.glove.write_feedback(self._feedback)  # the force display starts with the episode
        self._show()
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
        return self._observation(), self._info(terms, rest, self._fault)

    def step(self, action: NDArray[Any]) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        if self.glove is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or inf: {a.tolist()}; actions must be finite")
        a = np.minimum(np.maximum(a, -1.0), 1.0)  # np.clip of finite values, cheaper
        # Low-pass the calibrated angles: the sensor noise, amplified by the calibration,
        # would shake the fingers at the glove's rate and shake the pen loose.
        theta, ok = self._read_theta(self._theta)
        self._theta += self._alpha * (theta - self._theta)
        if not ok and not self._fault:
            self._fault = NONFINITE_THETA_FAULT
        fault = self.glove.fault or self._fault
        target = self._theta + self.config.action_scale * a  # finite: theta and a are
        m, d = self.model, self.data
        d.ctrl[self._act] = np.minimum(np.maximum(target, self._ctrl_lo), self._ctrl_hi)
        warnings_before = sum(self._warnings.tolist())
        mujoco.mj_step(m, d, self.frame_skip)
        self._steps += 1
        # A diverging simulation makes MuJoCo warn (and reset its data), as in the pen
        # tasks (PenHandEnv.step); a state that is not finite is put back to the start.
        finite = bool(np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all())
        self._unstable = sum(self._warnings.tolist()) > warnings_before or not finite
        if not finite:
            self._place_hand(self._theta)
        self._feedback, self._touch, self._pinch_force, rest = self._force_display()
        self.glove.write_feedback(self._feedback)
        self._show()

        terms = self._rewards(a)
        reward = float(sum(terms.values()))
        offset = self.data.xpos[self._pen_body] - self._pen_start
        cfg = self.config
        terminated = not self._unstable and bool(
            # |offset| as np.linalg.norm takes it (sqrt of the dot product), without its wrapper.
            offset[2] < -cfg.drop_height or math.sqrt(offset.dot(offset)) > cfg.max_distance
        )
        truncated = self._steps >= self.max_steps or bool(fault) or self._unstable
        return self._observation(), reward, terminated, truncated, self._info(terms, rest, fault)

    def __getstate__(self) -> dict[str, Any]:
        """Refuse clearly: the env holds a live glove device (simulated or real)."""
        raise TypeError(
            "IAS-GloveGrasp-v0 holds a live glove device and cannot be pickled; build a new "
            "env with the same glove_factory and calibration instead"
        )

    def close(self) -> None:
        if self.glove is not None:
            self.glove.close()
            self.glove = None
        super().close()  # the renderer
