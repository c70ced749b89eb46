"""Executing a transferred skill on a hand and measuring it (paper Flow 2).

:func:`run_transfer` runs one reference from :func:`ias_gym.skills.transfer.transfer_reference`
in ``IAS-PenSkill-v0`` with one of :data:`METHODS` (the grip-transform expert, Theorem 1 on
the skill's reference and margin, the kinematic baseline, or the retargeting baseline) and
returns a
:class:`TransferRun`: the env's verdict, the errors against the success test's tolerances
and the traces a figure plots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import InputError
from ias_gym.rollout import rollout

if TYPE_CHECKING:  # imported when used: reading references does not load the policies
    from ias_gym.baselines.gains import ControllerGains

FloatArray = NDArray[np.float64]


#: Methods of executing a transferred skill: the grip-transform expert (Theorem 1 on the
#: skill's reference and margin), the kinematic baseline and the retargeting baseline
#: (dex-retargeting and joint position control, the ``retarget`` extra).
METHODS: tuple[str, ...] = ("gt", "kinematic", "retarget")

#: The integral gain of the pen's position error [1/s^3]
#: (:attr:`~ias_gym.baselines.gains.ControllerGains.ki`) with which the
#: expert executes a transferred skill, per hand; fitted on development persons by
#: ``train/fit_gain.py --gain ki --per-hand`` (docs/controller.md). The pen tasks' expert
#: keeps the default (0).
TRANSFER_KI: dict[str, float] = {"ias4f": 500.0, "ias3f": 2000.0, "shadow": 0.0, "leap": 0.0}

#: How long a tip's ratio sits at its ceiling before it reads the pen's friction [s]
#: (:attr:`~ias_gym.baselines.gains.ControllerGains.plateau_time`), per hand; fitted on
#: development persons by ``train/fit_gain.py --gain plateau_time --per-hand``
#: (docs/controller.md). The IAS hands' tips stick and can hold one ratio for many steps, so
#: they take no ceiling reading.
TRANSFER_PLATEAU: dict[str, float] = {"ias4f": 0.0, "ias3f": 0.0, "shadow": 0.05, "leap": 0.05}


def transfer_gains(hand: str) -> ControllerGains:
    """The expert's :class:`~ias_gym.baselines.gains.ControllerGains` for a
    skill transferred to ``hand``: the defaults, with the hand's :data:`TRANSFER_KI` and
    :data:`TRANSFER_PLATEAU`."""
    from ias_gym.baselines.gains import ControllerGains

    return ControllerGains(
        ki=TRANSFER_KI.get(hand, 0.0), plateau_time=TRANSFER_PLATEAU.get(hand, 0.0)
    )


@dataclass
class TransferRun:
    """One execution of a transferred skill by one hand, with its traces.

    Attributes:
        hand, method: which hand, which method (``gt``, ``kinematic`` or ``retarget``).
        skill_id: the skill's id in its database; person, name: its provenance.
        success: the env's ``is_success``: ``held``, ``tracked`` and ``margin_kept``.
        held: the pen held for the whole episode; tracked: RMS rotation and position
            errors within the reference's tolerances; margin_kept: the margin error within
            its tolerance.
        held_s: how long the pen was held [s] (the episode's length unless dropped; the
            RMS errors are over that time).
        rot_rms_deg: RMS angle between the pen's axis and the reference's [deg].
        pos_rms_mm: RMS distance of the pen's centre from the reference's [mm].
        margin_err_rel: mean ``|m - m_ref| / m_ref`` of the grasp margin [-].
        scale, scale_rotation: the reference's translation and rotation scales [-].
        tolerance: the success test's ``rot_rms_deg``, ``pos_rms_mm``, ``margin_err_rel``.
        time: ``(T,)`` [s]; position, reference_position: ``(T, 3)`` [m]; axis,
        reference_axis: ``(T, 3)``; margin, margin_reference: ``(T,)`` [-];
        internal_forces: ``(T, n)`` measured ``c_h`` [N]; contact_forces: ``(T, k, 3)`` [N].
    """

    hand: str
    method: str
    skill_id: int
    person: str
    name: str
    success: bool
    held: bool
    tracked: bool
    margin_kept: bool
    held_s: float
    rot_rms_deg: float
    pos_rms_mm: float
    margin_err_rel: float
    scale: float
    scale_rotation: float
    tolerance: dict[str, float]
    time: FloatArray
    position: FloatArray
    reference_position: FloatArray
    axis: FloatArray
    reference_axis: FloatArray
    margin: FloatArray
    margin_reference: FloatArray
    internal_forces: FloatArray
    contact_forces: FloatArray

    def to_json(self) -> dict[str, Any]:
        """The metrics as a JSON-ready dict (units in the keys; NaN becomes ``None``)."""

        def number(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "hand": self.hand,
            "method": self.method,
            "skill_id": self.skill_id,
            "person": self.person,
            "skill": self.name,
            "success": self.success,
            "held": self.held,
            "tracked": self.tracked,
            "margin_kept": self.margin_kept,
            "held_s": self.held_s,
            "rot_rms_deg": number(self.rot_rms_deg),
            "pos_rms_mm": number(self.pos_rms_mm),
            "margin_err_rel": number(self.margin_err_rel),
            "scale": self.scale,
            "scale_rot": self.scale_rotation,
            "tolerance": {k: number(v) for k, v in self.tolerance.items()},
        }


class _Executing:
    """A policy that acts on another reference than the one its env judges it by (the
    weak executions that check the success test: a still pen, a constant margin)."""

    def __init__(self, policy: Any, env: PenSkillEnv, executed: SkillReference) -> None:
        self.policy, self.env, self.executed = policy, env, executed

    def predict(self, observation: Any, *args: Any, **kwargs: Any) -> Any:
        judged = self.env.references
        self.env.references = (self.executed,)
        try:
            return self.policy.predict(observation, *args, **kwargs)
        finally:
            self.env.references = judged


def run_transfer(
    reference: SkillReference,
    hand: str = "ias4f",
    method: str = "gt",
    seed: int = 0,
    render: bool = False,
    executed: SkillReference | None = None,
    gains: Any = None,
    reset_options: dict[str, Any] | None = None,
    **config: Any,
) -> tuple[TransferRun, list[NDArray[Any]]]:
    """Execute a transferred skill on a hand and measure it.

    Args:
        reference: from :func:`transfer_reference` for this hand.
        hand: the hand.
        method: ``"gt"`` (the grip-transform expert: Theorem 1 with the skill's margin),
            ``"kinematic"`` (:class:`~ias_gym.baselines.kinematic.KinematicPolicy`) or
            ``"retarget"`` (:class:`~ias_gym.baselines.retarget.RetargetPolicy`).
        seed: the reset seed.
        render: also return ``rgb_array`` frames (every other step: 50 fps).
        executed: the policy acts on this reference instead (same length of episode),
            while the run is still judged against ``reference``: a deliberately weak
            execution (e.g. the pen held still) that the success test must fail.
        gains: the method's gains: the expert's
            :class:`~ias_gym.baselines.gains.ControllerGains`, the
            kinematic baseline's :class:`~ias_gym.baselines.kinematic.KinematicGains` or
            the retargeting baseline's :class:`~ias_gym.baselines.retarget.RetargetGains`
            (default: its own; the expert's: :func:`transfer_gains`).
        reset_options: further options of the reset (e.g. an exact start, ``qpos`` and
            ``qvel``); the skill is always the reference.
        **config: further :class:`PenSkillConfig` fields.

    Returns:
        ``(run, frames)``; ``frames`` is empty unless ``render``.

    Raises:
        InputError: an unknown method, or ``retarget`` without dex-retargeting installed.
    """
    # the policies: imported here, so that reading references does not load them
    from ias_gym.baselines.expert import ExpertPolicy
    from ias_gym.baselines.kinematic import KinematicPolicy

    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; methods: {list(METHODS)}")
    env = PenSkillEnv(
        render_mode="rgb_array" if render else None, references=[reference], hand=hand, **config
    )
    try:
        policy: Any
        if method == "gt":
            policy = ExpertPolicy(env, gains or transfer_gains(hand))
        elif method == "kinematic":
            policy = KinematicPolicy(env, gains)
        else:
            from ias_gym.baselines.retarget import RetargetPolicy

            policy = RetargetPolicy(env, gains)
        if executed is not None:
            policy = _Executing(policy, env, executed)
        rows: dict[str, list[Any]] = {
            k: [] for k in ("t", "p", "pr", "a", "ar", "m", "mr", "ch", "cf")
        }
        frames: list[NDArray[Any]] = []

        def sample(_env: Any, *args: Any) -> None:  # after the reset and every step
            info = args[-1]
            ref = env.reference()
            rows["t"].append(env.time)
            rows["p"].append(env.state.position.copy())
            rows["pr"].append(ref.position)
            rows["a"].append(env.state.axis.copy())
            rows["ar"].append(ref.axis)
            rows["m"].append(env.grasp_margin())
            rows["mr"].append(info["margin_reference"])
            rows["ch"].append(info["internal_forces"])
            rows["cf"].append(info["contact_forces"])
            if render and env._steps % 2 == 0:
                frame = env.render()
                if frame is not None:
                    frames.append(frame)

        trajectory = rollout(
            env,
            policy,
            seed,
            reset_options={**(reset_options or {}), "skill": 0},
            keep_observations=False,
            keep_infos=False,
            on_reset=sample,
            on_step=sample,
        )
        held = env.held()
        tolerance = env.tolerance()
    finally:
        env.close()
    info = trajectory.final_info
    run = TransferRun(
        hand=hand,
        method=method,
        skill_id=reference.skill_id,
        person=reference.person,
        name=reference.name,
        success=bool(info["is_success"]),
        held=held,
        tracked=bool(info["tracked"]),
        margin_kept=bool(info["margin_kept"]),
        held_s=round(float(rows["t"][-1]), 6),  # MuJoCo's clock sums its steps: 2.9999999999998
        rot_rms_deg=math.degrees(info["rms_rotation_error"]),
        pos_rms_mm=1000.0 * info["rms_position_error"],
        margin_err_rel=env.margin_error(),
        scale=reference.scale,
        scale_rotation=reference.scale_rotation,
        tolerance={
            "rot_rms_deg": math.degrees(tolerance["rotation"]),
            "pos_rms_mm": 1000.0 * tolerance["position"],
            "margin_err_rel": tolerance["margin"],
        },
        time=np.array(rows["t"]),
        position=np.array(rows["p"]),
        reference_position=np.array(rows["pr"]),
        axis=np.array(rows["a"]),
        reference_axis=np.array(rows["ar"]),
        margin=np.array(rows["m"], dtype=float),
        margin_reference=np.array(rows["mr"], dtype=float),
        internal_forces=np.array(rows["ch"], dtype=float),
        contact_forces=np.array(rows["cf"], dtype=float),
    )
    return run, frames
