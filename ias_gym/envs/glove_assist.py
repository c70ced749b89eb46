"""IAS-GloveAssist-v0: the glove world with an impaired operator, for an assistant to help.

Paper, Flow 3: the assistant "identifies and anticipates the action the human operator wants
to perform, and if the necessary skill has been stored in the skill data base before, it is
applied". The world is ``IAS-GloveGrasp-v0``'s (physics, calibration, force display, reward,
success) with a skill always set, an operator impaired as :mod:`ias_gym.glove.impairments`
says, and the assistant as the agent: its action is the env's action, offsets of the hand's
joint targets on top of the operator's calibrated Θ.

The assistant sits between the glove and the hand: the glove is read one sample ahead
(:class:`~ias_gym.glove.impairments.PeekGlove`), and the observation ends with the joint
targets the operator's next reading will give (:attr:`GloveAssistEnv.upcoming_theta`), so
an offset corrects the command the hand is about to get, not the one it got 10 ms ago.

The operator is IAS-GloveGrasp-v0's (``operator``): by default the person in the loop
(:class:`~ias_gym.glove.closed_loop.ClosedLoopOperator`), who grips by the force they feel
and corrects the pen's pose by what they see, with the impairment inside the loop (a weak
grip is their plan's, a lag is the glove's, so they see their own commands arrive late); or
the open ``"script"``. Reading the glove one sample ahead makes the person's next command
10 ms earlier than the hand gets it, well inside their own visual and tactile delays.

An intent switch (``switch_to``, ``switch_time``): the operator performs ``skill`` until
``switch_time`` [s], then, blended over :data:`SWITCH_BLEND` [s], ``switch_to`` (its motion
at the phase it has then); :meth:`GloveAssistEnv.intent` is the skill intended at a time.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.envs.glove_readings import person_in_the_loop
from ias_gym.envs.glove_world import OBSERVATION_PARTS as GLOVE_PARTS
from ias_gym.envs.layout import observation_layout
from ias_gym.errors import InputError
from ias_gym.glove.device import GloveDevice, SimulatedGlove, min_jerk
from ias_gym.glove.hand import JOINT_HIGH, JOINT_LOW, N_JOINTS, PersonParams
from ias_gym.glove.impairments import (
    Impairment,
    LaggedGlove,
    PeekGlove,
    StopsOperator,
    TremorOperator,
    WeakGripOperator,
    biased_calibration,
    check_hand_scale,
    resized_person,
    session_rng,
    stock_person,
)
from ias_gym.glove.operator import FromPreShape, ScriptedOperator, skill_operator
from ias_gym.glove.profile_cache import default_calibration
from ias_gym.glove.skills import SKILL_TIMINGS, SkillOperator, check_skill

FloatArray = NDArray[np.float64]

#: Length of the blend from one skill's motion to the other's at an intent switch [s].
SWITCH_BLEND = 0.2
#: The observation: IAS-GloveGrasp-v0's parts and the upcoming joint targets [rad].
OBSERVATION_PARTS = (*GLOVE_PARTS, ("upcoming_theta", N_JOINTS))
#: Size of the observation.
OBS_SIZE = sum(size for _, size in OBSERVATION_PARTS)


class SwitchingOperator(SkillOperator):
    """Skill ``a`` until script time ``t_switch`` [s], then ``b`` (the same pinch-lift and
    person; only the skill's joint offsets blend, over :data:`SWITCH_BLEND`). A skill plan
    whose :attr:`skill` is ``b`` (where the person ends up) and whose motion lasts until the
    later of the two ends.

    Args:
        a, b: the two skills' operators (same base script).
        t_switch: script time of the switch [s].
    """

    def __init__(self, a: SkillOperator, b: SkillOperator, t_switch: float) -> None:
        super().__init__(a.base, b.skill, a.style)
        self.a, self.b, self.t_switch = a, b, float(t_switch)

    @property
    def duration(self) -> float:
        """Script time [s] at which both skills' motions have ended."""
        return max(self.a.duration, self.b.duration)

    def offsets(self, t: float) -> FloatArray:
        """The blend of the two skills' joint offsets ``(10,)`` [rad] at script time ``t``."""
        w = min_jerk((t - self.t_switch) / SWITCH_BLEND)
        out: FloatArray = (1.0 - w) * self.a.offsets(t) + w * self.b.offsets(t)
        return out


class GloveAssistEnv(GloveGraspEnv):
    """The glove world with an impaired operator and an assistant as the agent
    (``IAS-GloveAssist-v0``).

    ## Description
    ``IAS-GloveGrasp-v0`` performing ``skill`` (default ``lift_hold``), its operator impaired
    as the spec ``impairment`` says (:mod:`ias_gym.glove.impairment_spec`: ``none``, a
    family ``tremor``, ``weak_grip``, ``lag``, ``biased_calibration``, ``hand_size`` or
    ``stops`` with its parameters, e.g. ``"tremor:hz=5"``, families joined by ``+``, or
    ``sampled``: a family and its parameters drawn from the person's id and the skill).
    With zero action the session is the impaired operator alone: by default a person in
    the loop (``operator="closed_loop"``), or the open script (``operator="script"``).

    ## Action Space
    As IAS-GloveGrasp-v0: ``Box(-1, 1, (10,))``, offsets of the joint targets times
    ``action_scale`` [rad].

    ## Observation Space
    ``(49,)`` float64: IAS-GloveGrasp-v0's 39, then the joint targets the operator's next
    reading gives (10) [rad] (:attr:`upcoming_theta`). By name:
    ``env.unwrapped.observation_layout[name]`` is the part's slice
    (:data:`OBSERVATION_PARTS` in order):

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
    | ``upcoming_theta`` | 10 | the joint targets the operator's next reading gives [rad] |

    ## Rewards
    As IAS-GloveGrasp-v0: ``lift``, ``pinch``, ``effort``.

    ## Starting State
    As IAS-GloveGrasp-v0.

    ## Episode End
    As IAS-GloveGrasp-v0.

    ## Arguments
    ``render_mode``; ``impairment`` [``"none"``]; ``strength`` [None: the spec's]: the size
    of a family given by its bare name (``impairment_spec.STRENGTH_KEY``);
    ``switch_to`` [None]: a skill the operator switches to at ``switch_time`` [s, episode
    time]; ``hand_scale`` [None]: the person with their hand resized to this scale
    (:func:`~ias_gym.glove.impairments.resized_person`), the operator planning for that
    hand (``hand_size`` with the same scale runs the stock plan on it instead); and the
    fields of :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig`
    (``person_id``, ``skill``, ``control_dt``, ``duration``, ``action_scale``, ``operator``
    [``"closed_loop"``], ...).

    ## Version History
    - v0: first version (the impairment ``hand_size`` replaced ``small_hand``, a hand of
      scale 0.8 judged against the person's own hand, before any release).

    Attributes:
        impairment: the :class:`~ias_gym.glove.impairment_spec.Impairment` (``sampled``
            resolved: the drawn one).
        operator_person: whose hand the operator's script plans for (``hand_size``: the
            stock hand; else the hand's owner).
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        impairment: str = "none",
        strength: float | None = None,
        switch_to: str | None = None,
        switch_time: float | None = None,
        hand_scale: float | None = None,
        **config: Any,
    ) -> None:
        """Build the env.

        Args:
            render_mode: ``None`` or ``"rgb_array"``.
            impairment: the operator's impairment spec.
            strength: the size of a bare family name (None: the spec's).
            switch_to: a skill the operator switches to (None: no switch).
            switch_time: episode time of the switch [s] (needed with ``switch_to``).
            hand_scale: resize the person's hand to this scale [-], the operator's plan
                made for it (None: the person's own hand).
            **config: fields of :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig`.

        Raises:
            InputError: an unknown impairment family, key or skill, a value out of range,
                ``switch_to`` without a non-negative ``switch_time``, or ``hand_scale`` out
                of (0, 2] or given with ``hand_size``.
        """
        config.setdefault("skill", "lift_hold")
        imp = Impairment.make(impairment, strength)
        person_id = str(config.get("person_id", "p1"))
        self.impairment = imp.draw(session_rng("sampled", person_id, str(config["skill"])))
        if switch_to is not None:
            check_skill(switch_to, "switch_to")
            if switch_time is None or not switch_time >= 0:
                raise InputError("switch_to needs switch_time >= 0 [s, episode time]")
        self.switch_to = switch_to
        self.switch_time = None if switch_to is None else float(switch_time)  # type: ignore[arg-type]
        owner = PersonParams.sample(person_id)
        imp = self.impairment
        size, bias = imp.family("hand_size"), imp.family("biased_calibration")
        if hand_scale is not None:
            check_hand_scale(hand_scale, "hand_scale")
            if size is not None:
                raise InputError(
                    "hand_scale is a hand whose operator plans for it; hand_size's strength "
                    "is the scale of a hand running the stock plan: give one of the two"
                )
            owner = resized_person(owner, float(hand_scale))
        hand = owner if size is None else resized_person(owner, size.number("scale"))
        self.operator_person = owner if size is None else stock_person(owner)
        calibration = default_calibration(hand)
        if bias is not None:
            calibration = biased_calibration(calibration, bias.number("rad"), str(bias["fingers"]))
        super().__init__(render_mode, person=hand, calibration=calibration, **config)
        m = self.model
        radius = float(m.geom_size[m.geom("pen").id, 0])
        skill = str(self.config.skill)
        script: ScriptedOperator = skill_operator(self.operator_person, radius, skill)
        if switch_to is not None:
            assert self.switch_time is not None
            other = skill_operator(self.operator_person, radius, switch_to)
            assert isinstance(script, SkillOperator)
            script = SwitchingOperator(script, other, self.switch_time + SKILL_TIMINGS.reach)
        self.script = script
        self.glove_factory = self._impaired_glove
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(OBS_SIZE,), dtype=np.float64)
        self.observation_layout = observation_layout(OBSERVATION_PARTS)
        #: The joint targets [rad] the operator's next reading gives (IAS-GloveGrasp-v0's
        #: calibration, clipping and low-pass applied), before any action.
        self.upcoming_theta = np.zeros(N_JOINTS)

    def _impaired_glove(self, seed: int) -> GloveDevice:
        imp = self.impairment
        script: ScriptedOperator = self.script
        stops, weak = imp.family("stops"), imp.family("weak_grip")
        tremor, lag = imp.family("tremor"), imp.family("lag")
        if stops is not None and isinstance(script, SkillOperator):
            script = StopsOperator(script, stops.number("at"))
        if weak is not None:
            script = WeakGripOperator(script, weak.number("rad"), str(weak["fingers"]))
        if tremor is not None:
            amplitude, hz = tremor.number("amplitude_rad"), tremor.number("hz")
            script = TremorOperator(script, amplitude, hz, self.person.person_id, seed)
        if self.config.operator == "closed_loop":
            self.operator = person_in_the_loop(self.model, script, self.operator_person)
            glove: GloveDevice = SimulatedGlove(self.person, self.operator, seed)
        else:
            glove = SimulatedGlove(self.person, FromPreShape(script), seed)
        if lag is not None:
            glove = LaggedGlove(glove, round(lag.number("s") / self.config.control_dt))
        return PeekGlove(glove)

    def intent(self, time_s: float) -> str:
        """The skill the operator intends at episode time ``time_s`` [s]."""
        if self.switch_to is not None and self.switch_time is not None:
            if time_s >= self.switch_time:
                return self.switch_to
        return str(self.config.skill)

    def _observation(self) -> FloatArray:
        base = super()._observation()
        glove = self.glove
        if isinstance(glove, PeekGlove):
            psi = glove.upcoming.psi
            theta = np.asarray(self.calibration.predict(psi), dtype=np.float64)
            if np.isfinite(theta).all():
                theta = np.clip(theta, JOINT_LOW, JOINT_HIGH)
                self.upcoming_theta = self._theta + self._alpha * (theta - self._theta)
            else:
                self.upcoming_theta = self._theta.copy()
        else:
            self.upcoming_theta = self._theta.copy()
        return np.concatenate([base, self.upcoming_theta])

    def _info(self, terms: dict[str, float], rest: bool, fault: str) -> dict[str, Any]:
        info = super()._info(terms, rest, fault)
        info["intent"] = self.intent(self._steps * self.config.control_dt)
        info["impairment"] = self.impairment.name
        info["operator_theta"] = self._theta.copy()
        return info
