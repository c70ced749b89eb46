"""The analytic assistant: complete the recognised skill from its stored model (paper Flow 3).

Every control step :class:`AnalyticAssistant` reads the operator's upcoming joint targets Θ
(``IAS-GloveAssist-v0``'s :attr:`~ias_gym.envs.glove_assist.GloveAssistEnv.upcoming_theta`; on
another glove env, e.g. ``IAS-GloveHardware-v0``, the last applied ones), asks its recogniser
for the posterior over the library's skills and returns joint-target offsets, the sum of

1. **tremor removal**: a causal band-stop (Butterworth of order :data:`TREMOR_ORDER`,
   :data:`TREMOR_STOP` Hz, scipy) on the wrist and pinching joints; offset = filtered Θ - Θ.
   It acts only once a band-pass detector has seen a tremor (:data:`TREMOR_DETECT`, within
   :data:`TREMOR_WINDOW`), so an operator without one is left alone;
2. **the squeeze**, four parts; only the last ever opens the operator's grip:

   - *the opening*: the operator's pinch joints are compared with the library's joint
     template (every skill starts with the same pinch-lift) along the pinch's closing
     direction (:func:`~ias_gym.glove.impairments.pinch_direction`: index MCP, PIP/2,
     thumb flexion), twice. At rest (:data:`REST_WINDOW`), finger by finger: both fingers
     opened beyond :data:`BIAS_THRESHOLD` is a biased calibration, in every reading, and
     the less opened finger's opening is added from then on, the close included. In the
     hold before the lift (:data:`OPENING_WINDOW`), what the pinch lacks beyond
     :data:`OPENING_DEADBAND` (without a bias), or what its closing from rest lacks
     beyond :data:`CLOSING_DEADBAND`, is added as well (a weak grip; a person whose own
     pinch is closer than the library's hides it from the first estimate, not from the
     second);
   - *reactive closing* until the end of the lift (:data:`LIFT_END`), and after it only
     where the hold found the pinch opened beyond a bias (an unimpaired grip, and a biased
     one undone from rest, is left alone): an integrator on the
     larger of the live grasp margin's relative error against the library's (the soft
     fingers' cones, :func:`~ias_gym.grasp.grasp_margin.grasp_margin`, the pads' friction and
     torsion read from the scene, as :func:`~ias_gym.skills.transfer.demonstrated_margin`
     measures the library) and the pinch force's against :data:`FORCE_SHARE` of the
     library's, plus a slip reflex (:data:`SLIP_RATE` while the margin is at the cones'
     boundary), neither for a pinch already pressing :data:`FIRM_FORCE` times the
     library's force; it closes along the line between the pads
     (:func:`~ias_gym.assist.pinch_geometry.closing_direction`);
   - after the close phase, a pinch with a pad off the pen closes at :data:`CLOSE_RATE`;
   - *the pad that comes to the pen first waits for the other*
     (:meth:`AnalyticAssistant._coordinate_offset`): until the close's end
     (:data:`COORDINATE_UNTIL`), once that pad (not one the pen rests on before the close)
     has pushed the pen :data:`PUSH_DISTANCE` before the other ever touched it, and no
     tremor is detected, its finger is held back to the pose at which it first touched
     (never closer, from then on; let go over :data:`HOLD_RELEASE` where the hold found the
     pinch opened), and the other finger reaches toward it along its part of the pads'
     line (:data:`REACH_RATE`, up to :data:`MAX_REACH`) while it is off the pen. A hand
     larger than the one the operator plans for (``hand_size``) brings the index to the
     pen first, and the index drags it off its support before the thumb arrives;
3. **the object's height toward the template**: from the middle of the lift, an integrator
   on the wrist's flexion drives the pen's height above its start into the template's band
   (``sum_k p_k z_k(tau)`` for ``tau`` within :data:`HEIGHT_TIME_TOLERANCE` of now: the
   library's mean object trajectory, a person early or late as the success test allows;
   ``tau`` aligned at the operator's start as the assistant sees it,
   :meth:`AnalyticAssistant._template_time`), ignoring errors up to
   :data:`HEIGHT_DEADBAND` (a person's own way of lifting).

Confidence blending: term 3 is weighted by the posterior (the unknown share adds nothing),
term 2's targets are the posterior's mean (the unknown share takes the library's median);
term 1 is the same for every skill.

Lag compensation was tried and dropped (docs/assistance.md): a scripted operator does not
close a loop through the lag, so a lag only delays the session, and predicting the
operator's motion 0.1 s ahead from the library (another person's speed) or from its own
recent past made lagged sessions worse.

:class:`~ias_gym.assist.oracle_recogniser.OracleRecogniser` has the recogniser protocol
(``reset``, ``update``, ``add_skill``, ``skills``) and knows the true intent (the env's
:meth:`~ias_gym.envs.glove_assist.GloveAssistEnv.intent`): the upper bound of recognition,
and the stand-in until a learned recogniser is given.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfilt, sosfilt_zi

from ias_gym.assist.oracle_recogniser import OracleRecogniser
from ias_gym.assist.pinch_geometry import CLOSING_JOINTS, closing_direction, live_margin
from ias_gym.assist.sessions import LIFT_END, MAX_TIME_SHIFT
from ias_gym.assist.skill_motions import MOVING_JOINT
from ias_gym.assist.skill_templates import SkillTemplate
from ias_gym.assist.stream import frames_from_env
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS, joint_index
from ias_gym.glove.impairments import TREMOR_JOINTS, pinch_direction
from ias_gym.glove.skills import SKILL_TIMINGS

FloatArray = NDArray[np.float64]

#: Stop band of the tremor filter [Hz] (the tremor band 8-12 Hz, widened by 1 Hz).
TREMOR_STOP = (7.0, 13.0)
#: Order of the band-stop: 4 takes a tremor at the band's edges (8.5 or 11.5 Hz) down by
#: 19-33 dB (2nd order: 10-17 dB, and the pen still slipped out of a held pinch) for a
#: phase lag of 16 deg at the fast see-saw's 1.5 Hz.
TREMOR_ORDER = 4
#: The tremor filter acts once the RMS of the operator's tremor joints in the tremor band
#: (a 2nd-order Butterworth band-pass, :data:`DETECT_BAND`) over
#: :data:`TREMOR_WINDOW` exceeds this [rad]. Measured over the first 0.5 s of 30 sessions
#: (five development persons, six skills) after the env's low-pass: unimpaired <= 0.0017, a
#: 0.06 rad tremor >= 0.0091.
TREMOR_DETECT = 0.004
#: Band of the tremor detector's band-pass [Hz] (the tremors this assistant was made for).
DETECT_BAND = (8.0, 12.0)
#: Window of the tremor detector [s].
TREMOR_WINDOW = 0.15
#: The pinch's opening against the library's joint template is estimated over this window
#: of episode time [s]: the hold before the lift, where the pinch is closed and every
#: skill's template is the same pinch-lift ...
OPENING_WINDOW = (
    SKILL_TIMINGS.close - SKILL_TIMINGS.reach + 0.1,
    SKILL_TIMINGS.hold - SKILL_TIMINGS.reach,
)
#: ... and the part of it up to this is a person's own pinch, not closed by the assistant
#: [rad] (unimpaired development persons lie within -0.037..+0.029 rad of the template).
OPENING_DEADBAND = 0.03
#: The same comparison at rest, before the close, finger by finger: a biased calibration
#: shifts every reading, the rest pose's too, and opens both fingers along the pinch's
#: direction, where a person's own rest pose differs from the library's in the index
#: (-0.05..+0.07 rad) but hardly in the thumb (+-0.011 rad) ...
REST_WINDOW = (0.0, 0.1)
#: ... so a rest pose whose less opened finger is opened by more than this is a bias, closed
#: by that finger's opening from then on [rad] (18 development persons, 3 seeds: unimpaired,
#: lagged, tremoring, weak and a larger hand (``hand_size``: the index alone) <= +0.020;
#: biased by 0.10 rad >= +0.063, the index of a person whose own rest is more closed).
BIAS_THRESHOLD = 0.04
#: The pinch's closing from rest to the hold against the template's, beyond this, is an
#: opening too [rad]: it leaves out where a person's pinch pose differs from the library's
#: and their rest pose by as much (the same persons: unimpaired <= 0.000; weak grip
#: -0.018..+0.087, against -0.023..+0.085 for the hold's pose alone).
CLOSING_DEADBAND = 0.01
#: Share of the library's pinch force below which the squeeze is raised [-] (a person's own
#: squeeze differs from the library's by tens of percent).
FORCE_SHARE = 0.75
#: A pinch pressing this many times the library's pinch force is firm: its margin and slips
#: raise no squeeze [-]. Unimpaired persons press 1.5-4.3 N against the library's 1.5 N
#: (development persons, the lift); a slip reflex on ha-e1d072's 4.3 N pinch squeezed the
#: pen out of an unimpaired fast see-saw at 3.7 s (measured).
FIRM_FORCE = 2.0
#: Gain of the squeeze integrator [rad/s per unit of relative margin or force error].
SQUEEZE_GAIN = 1.0
#: The slip reflex: below this grasp margin the pads slide on the pen (1 is the cones'
#: boundary, where MuJoCo's sliding contacts sit) [-] ...
SLIP_MARGIN = 1.02
#: ... and the pinch then closes at this rate while the lift loads the grasp [rad/s] (a
#: human grip's slip reflex raises the grip force within ~0.1 s of a slip).
SLIP_RATE = 0.75
#: Closing rate of a pinch with a pad off the pen after the close phase [rad/s].
CLOSE_RATE = 1.0
#: Largest reactive closing offset [rad].
MAX_SQUEEZE = 0.15
#: Episode time after which the pinch is closed and the squeeze is regulated [s] (the close
#: phase of the skills' pinch-lift lasts SKILL_TIMINGS.close - .reach = 0.7 s).
SQUEEZE_FROM = SKILL_TIMINGS.close - SKILL_TIMINGS.reach
#: Until this episode time [s] (the end of the close) the pad that reached the pen first
#: and pushes it alone is held back ...
COORDINATE_UNTIL = SKILL_TIMINGS.close - SKILL_TIMINGS.reach
#: ... once it has pushed the pen this far from its start [m] (a
#: ``hand_size`` index drags it 2 mm in 20-40 ms and off its support within 0.1 s;
#: measured on development persons: docs/assistance.md) ...
PUSH_DISTANCE = 0.002
#: ... and the other finger reaches toward it at this rate along its part of
#: :func:`~ias_gym.assist.pinch_geometry.closing_direction` [1/s] ...
REACH_RATE = 1.0
#: ... up to this offset [rad, 1-norm] ...
MAX_REACH = 0.4
#: ... until this episode time [s] (the lift's first half second).
REACH_UNTIL = SKILL_TIMINGS.hold - SKILL_TIMINGS.reach + 0.5
#: A held finger of a pinch found opened (term 2's opening) is let go over this time [s].
HOLD_RELEASE = 0.3
#: Gain of the height integrator on the wrist's flexion [rad/s per m of height error].
HEIGHT_GAIN = 40.0
#: Height errors up to this are the person's own way of lifting (or a late one), not
#: corrected [m].
HEIGHT_DEADBAND = 0.006
#: Largest wrist offset of the height correction [rad].
MAX_HEIGHT_OFFSET = 0.3
#: Episode time from which the pen's height follows the template [s] (the middle of the lift).
HEIGHT_FROM = 0.5 * (SKILL_TIMINGS.hold + SKILL_TIMINGS.lift) - SKILL_TIMINGS.reach
#: A pen as high as the template within this time of now is on time [s]: a person early or
#: late by up to the success test's time shift is no height error (a lagged operator lifts
#: 0.1 s late, and correcting that dropped the pen in a tilt, measured).
HEIGHT_TIME_TOLERANCE = MAX_TIME_SHIFT
_HEIGHT_SHIFTS = np.linspace(-HEIGHT_TIME_TOLERANCE, HEIGHT_TIME_TOLERANCE, 7)


#: The operator's skill has begun once their wrist left its pose at the lift's end by this
#: [rad]: what counts as a skill moving a joint
#: (:data:`~ias_gym.assist.skill_motions.MOVING_JOINT`), beyond the wrist's corrections of
#: the lifted pen and the end of a lagged lift (0.01 rad took a lagged lift's end for the
#: skill's start, measured).
ONSET_RAD = MOVING_JOINT


def onset_delay(template: SkillTemplate, joints: NDArray[np.int64]) -> float:
    """Time [s] from ``template``'s skill start until its ``joints`` leave their pose there
    by :data:`ONSET_RAD` (inf: they never do, e.g. a skill that holds still)."""
    k = int(np.searchsorted(template.time, template.start))
    away = np.abs(template.theta[k:, joints] - template.theta[k, joints]).max(axis=1)
    moved = np.flatnonzero(away > ONSET_RAD)
    return float(template.time[k + moved[0]] - template.start) if moved.size else math.inf


def _along(v: FloatArray, u: FloatArray) -> float:
    """The component of ``v`` along ``u``, in units of ``u``."""
    return float(u @ v / (u @ u))


class AnalyticAssistant:
    """Complete the recognised skill from its stored model (module docstring).

    Args:
        templates: the library's templates
            (:func:`~ias_gym.assist.skill_templates.load_templates`).
        recogniser: gives the posterior (the recogniser protocol); None: an
            :class:`~ias_gym.assist.oracle_recogniser.OracleRecogniser` on the env's
            intent, made at every :meth:`reset`.
        tremor_filter, squeeze, height: switch the three terms (ablations).
        coordinate: switch the lone pad's wait and the other pad's reach (part of term 2).
    """

    def __init__(
        self,
        templates: dict[str, SkillTemplate],
        recogniser: Any = None,
        *,
        tremor_filter: bool = True,
        squeeze: bool = True,
        height: bool = True,
        coordinate: bool = True,
    ) -> None:
        self.templates = templates
        self.recogniser = recogniser
        self._oracle = recogniser is None
        self.tremor_filter = tremor_filter
        self.squeeze = squeeze
        self.height = height
        self.coordinate = coordinate
        self._finger_idx = {
            site: np.array([joint_index(j) for j in joints])
            for site, joints in CLOSING_JOINTS.items()
        }
        self._tremor_idx = np.array([joint_index(j) for j in TREMOR_JOINTS])
        self._wf = JOINT_NAMES.index("wrist_flexion")
        self._wrist = np.array([self._wf, JOINT_NAMES.index("wrist_pronation")])
        self._onset_delays = {k: onset_delay(v, self._wrist) for k, v in templates.items()}
        self._least_delay = min(self._onset_delays.values(), default=math.inf)
        self._pinch = pinch_direction()
        self._pinch_fingers = []  # each finger's part of the pinch's direction
        for idx in self._finger_idx.values():
            part = np.zeros(N_JOINTS)
            part[idx] = self._pinch[idx]
            self._pinch_fingers.append(part)
        self._post: dict[str, float] = {}
        #: The height correction on the wrist's flexion [rad].
        self.h = 0.0
        #: The reactive closing offset along the pads' line [rad].
        self.g = 0.0
        #: The pinch's estimated opening, closed along the pinch's joints [rad].
        self.opening = 0.0
        #: The part of it seen at rest: a biased calibration [rad] (0: none seen).
        self.bias = 0.0
        #: Whether the tremor detector has fired in this session.
        self.tremor_detected = False
        #: Episode time [s] at which a pad pushing the pen alone was first held back (None:
        #: never in this session).
        self.coordinated_at: float | None = None

    def reset(self, env: Any) -> None:
        """Start a session on ``env`` (unwrapped, just reset)."""
        cfg = env.config
        self._dt = float(cfg.control_dt)
        self._scale = float(cfg.action_scale)
        if self._oracle:
            skill = str(cfg.skill)
            intent: Callable[[float], str] = getattr(env, "intent", lambda _t: skill)
            self.recogniser = OracleRecogniser(intent)
        self.recogniser.reset()
        fs = 1.0 / self._dt
        theta = self._operator_theta(env)[self._tremor_idx][None, None, :]
        self._stop = butter(TREMOR_ORDER, TREMOR_STOP, btype="bandstop", fs=fs, output="sos")
        self._stop_z = sosfilt_zi(self._stop)[:, :, None] * theta
        self._band = butter(2, DETECT_BAND, btype="bandpass", fs=fs, output="sos")
        self._band_z = sosfilt_zi(self._band)[:, :, None] * theta
        self._band_power: deque[float] = deque(maxlen=round(TREMOR_WINDOW / self._dt))
        self.tremor_detected = False
        self.g = 0.0
        self.h = 0.0
        self.opening = 0.0
        self.bias = 0.0
        self._openings: list[float] = []  # the hold's template - theta along d
        self._rest: list[FloatArray] = []  # template - theta at rest
        self.coordinated_at = None
        self._alone_from: dict[str, FloatArray] = {}  # finger -> its joints at first lone touch
        self._held: dict[str, FloatArray] = {}  # finger -> the pose it is held back to
        self._reach = np.zeros(N_JOINTS)
        self._release_at: float | None = None  # when a held finger began to be let go
        self._first_touch: str | None = None  # the pad that came to the pen first (or "both")
        self._both_touched = False
        self._theta_lift: FloatArray | None = None  # the operator's targets at LIFT_END
        self._onset: float | None = None  # when their skill's own motion was seen [s]
        self._post = {}

    @staticmethod
    def _operator_theta(env: Any) -> FloatArray:
        upcoming = getattr(env, "upcoming_theta", None)
        return np.array(env._theta if upcoming is None else upcoming, dtype=np.float64)

    def posterior(self) -> dict[str, float]:
        """The recogniser's posterior of the last :meth:`act`."""
        return dict(self._post)

    def _see_onset(self, t: float, theta: FloatArray) -> None:
        """Note when the operator's wrist (``theta``: their targets, a detected tremor
        filtered out) first leaves its pose at the lift's end by :data:`ONSET_RAD` (their
        skill's own motion has begun)."""
        if t < LIFT_END or self._onset is not None:
            return
        if self._theta_lift is None:
            self._theta_lift = theta.copy()
        if float(np.abs(theta - self._theta_lift)[self._wrist].max()) > ONSET_RAD:
            if t - self._least_delay < LIFT_END:  # no skill starts before the lift's end:
                self._theta_lift = theta.copy()  # this is the lift still ending (a lag)
            else:
                self._onset = t

    def _template_time(self, template: SkillTemplate, t: float) -> float:
        """Template time of the operator's intent at episode time ``t`` [s]: until their
        motion is seen, the episode time (every skill's pinch-lift is the same); then the
        operator's start, their onset less the template's own time to the same departure
        (:func:`onset_delay`), is the template's."""
        delay = self._onset_delays.get(template.name, math.inf)
        if self._onset is None or not math.isfinite(delay):
            return t
        return t - (self._onset - delay) + template.start

    def _tremor_offset(self, theta: FloatArray) -> FloatArray:
        """Term 1: the band-stop's correction, once the detector has seen a tremor."""
        x = theta[self._tremor_idx][None, :]
        y, self._stop_z = sosfilt(self._stop, x, axis=0, zi=self._stop_z)
        band, self._band_z = sosfilt(self._band, x, axis=0, zi=self._band_z)
        self._band_power.append(float(np.mean(band * band)))
        if not self.tremor_detected and len(self._band_power) == self._band_power.maxlen:
            self.tremor_detected = math.sqrt(float(np.mean(self._band_power))) > TREMOR_DETECT
        out = np.zeros(N_JOINTS)
        if self.tremor_detected:
            out[self._tremor_idx] = y[0] - x[0]
        return out

    def _squeeze_offset(self, env: Any, t: float, theta: FloatArray, post: Any) -> FloatArray:
        """Term 2: close a pinch opened against the template, and a slipping or lost one."""
        template = next(iter(self.templates.values()))  # the shared pinch-lift
        d = self._pinch
        if REST_WINDOW[0] <= t <= REST_WINDOW[1]:
            self._rest.append(template.at(t) - theta)
            rest = np.mean(self._rest, axis=0)
            both = min(_along(rest, f) for f in self._pinch_fingers)
            # a bias is in every reading: it is undone from here on, the close included
            self.opening = self.bias = both if both > BIAS_THRESHOLD else 0.0
        if OPENING_WINDOW[0] <= t <= OPENING_WINDOW[1]:
            self._openings.append(_along(template.at(t) - theta, d))
            hold = float(np.mean(self._openings))
            closing = hold - _along(np.mean(self._rest, axis=0), d) if self._rest else -math.inf
            # the hold's pose and the closing from rest each see an opening the other may
            # not (a person whose own pinch is closer than the library's hides a weak grip
            # in the first). Past a bias, only the closing: the hold's pose holds the bias,
            # estimated apart, and the person's own pinch
            beyond = closing - CLOSING_DEADBAND
            if not self.bias:
                beyond = max(beyond, hold - OPENING_DEADBAND)
            self.opening = self.bias + max(beyond, 0.0)
        if t < SQUEEZE_FROM:
            before: FloatArray = self.opening * d
            return before
        m = live_margin(env)
        if math.isnan(m):  # a pad off the pen
            self.g += CLOSE_RATE * self._dt
        # after the lift, only where the hold found the pinch opened: unimpaired grips slip
        # briefly in every fast skill, and reacting to that pushed their sessions out of
        # tolerance (measured)
        elif t <= LIFT_END or self._opened_in_hold():
            margins = [k.margin for k in self.templates.values()]
            forces = [k.force for k in self.templates.values()]
            target = sum(
                p * (self.templates[k].margin if k in self.templates else float(np.median(margins)))
                for k, p in post.items()
            )
            force = sum(
                p * (self.templates[k].force if k in self.templates else float(np.median(forces)))
                for k, p in post.items()
            )
            # the margin, and before the lift (the support carries the pen, the margin says
            # nothing) the pinch force against a share of the library's
            # a pinch already pressing FIRM_FORCE times the library's force does not slip
            # for want of force: it is left alone (and a squeeze from before unwinds)
            firm = float(env._pinch_force) >= FIRM_FORCE * force
            err_m = -math.inf if firm else (target - min(m, 2.0 * target)) / target
            err_f = (FORCE_SHARE * force - min(float(env._pinch_force), force)) / force
            self.g += SQUEEZE_GAIN * max(err_m, err_f) * self._dt
            if m < SLIP_MARGIN and not firm:
                self.g += SLIP_RATE * self._dt
        self.g = float(min(max(self.g, 0.0), MAX_SQUEEZE))
        out: FloatArray = self.opening * self._pinch + self.g * closing_direction(env)
        return out

    def _opened_in_hold(self) -> bool:
        """The hold found the pinch opened beyond a bias seen at rest. A bias undone from the
        start leaves the person's own pinch, which the reactive closing after the lift leaves
        alone as it does an unimpaired one (for a development person, its margin on the cones'
        boundary raised the squeeze to its cap and dropped the pen, measured)."""
        return self.opening > self.bias

    def _coordinate_offset(self, env: Any, t: float, theta: FloatArray) -> FloatArray:
        """Term 2, the close: a pad pushing the pen alone waits, the other reaches for it."""
        fingers = tuple(CLOSING_JOINTS)  # index, thumb: the order of env._touch
        touch = tuple(bool(v) for v in env._touch)
        alone = fingers[touch.index(True)] if touch[0] != touch[1] else None
        if any(touch) and self._first_touch is None:  # the first contact with the pen
            # a pad on the pen before the close begins is the one it rests on (the scene
            # lays the pen on the thumb pad), not one that came to it: it carries the pen in
            # the close. Not only at the first step: a bias undone from rest brings a thumb
            # the biased reading held off the pen onto it within 0.1 s, and taking it for a
            # pad that came first held it back 0.2 rad (ha-e1d072, measured)
            resting = t <= REST_WINDOW[1]
            self._first_touch = "resting" if resting else (alone if alone else "both")
        self._both_touched = self._both_touched or all(touch)
        # only the pad that reached the resting pen first, before the other ever touched it
        if alone is not None and alone == self._first_touch and not self._both_touched:
            first = self._alone_from.setdefault(alone, theta[self._finger_idx[alone]].copy())
            moved = float(np.linalg.norm(env.data.xpos[env._pen_body] - env._pen_start))
            # a tremor shakes a lone pad against the pen: that is no push (the filter's task)
            pushing = moved > PUSH_DISTANCE and not self.tremor_detected
            if alone not in self._held and pushing and t <= COORDINATE_UNTIL:
                self._held[alone] = first
                if self.coordinated_at is None:
                    self.coordinated_at = t
        if self._held and alone is not None and t <= REACH_UNTIL:
            other = self._finger_idx[fingers[1 - fingers.index(alone)]]
            step = np.zeros(N_JOINTS)
            step[other] = closing_direction(env)[other]
            self._reach += REACH_RATE * self._dt * step
            size = float(np.abs(self._reach).sum())
            if size > MAX_REACH:
                self._reach *= MAX_REACH / size
        # a pinch the hold found opened against the template (a weak grip) is short of
        # closing, not over it: the held finger is let go
        opened = self._opened_in_hold() and t > OPENING_WINDOW[1]
        if self._held and opened and self._release_at is None:
            self._release_at = t
        weight = 1.0
        if self._release_at is not None:
            weight = max(0.0, 1.0 - (t - self._release_at) / HOLD_RELEASE)
        out = self._reach.copy()
        for finger, pose in self._held.items():
            idx = self._finger_idx[finger]
            out[idx] += weight * np.minimum(pose - theta[idx], 0.0)  # never closer than that
        return out

    def _height_offset(self, env: Any, t: float, post: Any) -> FloatArray:
        """Term 3: the wrist's flexion drives the pen's height toward the template's band:
        the heights the template passes within :data:`HEIGHT_TIME_TOLERANCE` of now."""
        out = np.zeros(N_JOINTS)
        if t < HEIGHT_FROM:
            return out
        lo = hi = weight = 0.0
        for k, p in post.items():
            if k in self.templates:
                template = self.templates[k]
                tau = self._template_time(template, t)
                z = [template.height_at(tau + s) for s in _HEIGHT_SHIFTS]
                lo, hi, weight = lo + p * min(z), hi + p * max(z), weight + p
        z_pen = weight * float(env.data.xpos[env._pen_body][2] - env._pen_start[2])
        err = lo - z_pen if z_pen < lo else (hi - z_pen if z_pen > hi else 0.0)
        err = math.copysign(max(abs(err) - HEIGHT_DEADBAND, 0.0), err)
        self.h = float(
            np.clip(self.h + HEIGHT_GAIN * err * self._dt, -MAX_HEIGHT_OFFSET, MAX_HEIGHT_OFFSET)
        )
        out[self._wf] = -self.h  # extension (-) lifts the pen
        return out

    def act(self, env: Any) -> FloatArray:
        """The offsets ``(10,)`` (in action units, clipped to [-1, 1]) for the next step."""
        t = (env._steps + 1) * self._dt  # time of the reading the hand gets next
        theta = self._operator_theta(env)
        post = self.recogniser.update(frames_from_env(env))
        self._post = dict(post)
        offset = np.zeros(N_JOINTS)
        if self.tremor_filter:
            offset += self._tremor_offset(theta)
        self._see_onset(t, theta + offset)  # a tremor is no motion of the skill's
        if self.squeeze:
            offset += self._squeeze_offset(env, t, theta, post)
        if self.coordinate:
            offset += self._coordinate_offset(env, t, theta)
        if self.height:
            offset += self._height_offset(env, t, post)
        out: FloatArray = np.clip(offset / self._scale, -1.0, 1.0)
        return out
