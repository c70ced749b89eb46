"""The analytic assistant: complete the recognised skill from its stored model (paper Flow 3).

Every control step :class:`AnalyticAssistant` reads the operator's upcoming joint targets Θ
(``IAS-GloveAssist-v0``'s :attr:`~ias_gym.assist.env.GloveAssistEnv.upcoming_theta`; on
another glove env, e.g. ``IAS-GloveHardware-v0``, the last applied ones), asks its recogniser
for the posterior over the library's skills and returns joint-target offsets, the sum of

1. **tremor removal**: a causal band-stop (2nd-order Butterworth, :data:`TREMOR_STOP` Hz,
   scipy) on the wrist and pinching joints; offset = filtered Θ - Θ. Intended motion
   (the fastest skill, the fast see-saw, is 1.5 Hz) passes almost unchanged;
2. **lag compensation** (off by default: it made the held-out sessions worse,
   docs/assistance.md): the lag of the readings is estimated once, when the operator's
   lift crosses half its wrist extension, against the protocol's lift (the pinch-lift is
   timed alike for every person, :data:`~ias_gym.glove.skills.SKILL_TIMINGS`, seen through
   the env's low-pass); the wrist then gets the motion its own recent past predicts over
   that lag (a quadratic fitted to the last :data:`EXTRAPOLATION_WINDOW` filtered samples).
   The library's joint templates were tried first (``T_k(tau(t)) - T_k(tau(t - lag))``
   blended by the posterior) and made the fast see-saw worse: another person's speed
   (+-15 %) puts the template's phase off by more than the lag it should make up;
3. **the squeeze at the library's grasp margin**: the live grasp margin m (the soft-finger
   cones, :func:`~ias_gym.grasp.grasp_margin.grasp_margin`, mu = 0.25 and the pads'
   torsional friction, as :func:`~ias_gym.skills.transfer.demonstrated_margin` measures the
   library) is driven up to ``m* = sum_k p_k m_k`` (``m_k``: the median margin of skill k's
   demonstrations from their skill start; the unknown share gets the library's median) by an
   integrator on a closing offset ``g >= 0`` [rad] along the pinch's closing direction
   (:func:`~ias_gym.assist.impairments.pinch_direction`: index MCP, PIP/2, thumb
   flexion), on the larger of the relative margin error and the relative error of the pinch
   force against the library's (the margin says nothing while the support carries the
   pen); after the close phase a pinch with a pad off the pen closes at
   :data:`CLOSE_RATE`. ``g`` never opens the operator's own grip (it is >= 0) and leaks
   away where the margin is above ``m*``;
4. **the object's height toward the template**: from the middle of the lift, an integrator on the
   wrist's flexion drives the pen's height above its start toward the template's
   (``sum_k p_k z_k(tau(t))``, the library's mean object trajectory), ignoring errors up
   to :data:`HEIGHT_DEADBAND` (a person's own way of lifting).

Confidence blending: terms 2 and 4 are weighted by the posterior itself (the unknown share
adds nothing), term 3's target by it; term 1 is the same for every skill.

:class:`OracleRecogniser` has the recogniser protocol (``reset``, ``update``, ``add_skill``,
``skills``) and knows the true intent (the env's :meth:`~ias_gym.assist.env.GloveAssistEnv.intent`):
the upper bound of recognition, and the stand-in until a learned recogniser is given.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfilt, sosfilt_zi

from ias_gym.assist.impairments import TREMOR_JOINTS, pinch_direction
from ias_gym.assist.stream import SessionFrame, frames_from_env
from ias_gym.errors import InputError
from ias_gym.glove.device import ReachPinchLift
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS, WRIST_JOINTS, PersonParams, joint_index
from ias_gym.glove.skills import SKILL_TIMINGS, SKILLS, skill_start_time
from ias_gym.grasp.grasp_margin import grasp_margin
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import (
    GLOVE_PAD_TORSION,
    GLOVE_PEN_MU,
    demonstrated_margin,
    shipped_skill_db,
    skill_start_index,
)

FloatArray = NDArray[np.float64]

#: Stop band of the tremor filter [Hz] (the tremor band 8-12 Hz, widened by 1 Hz).
TREMOR_STOP = (7.0, 13.0)
#: Factor on the library's margin the squeeze is held at [-]: the library's median margin
#: dips to ~1.0 in fast motions (10th percentile), which an unimpaired grip survives and a
#: weakened one, held at the median only, does not.
MARGIN_FACTOR = 1.0
#: Share of the library's pinch force below which the squeeze is raised [-] (unimpaired
#: persons squeeze 1.2-1.6 N, the library 1.43 N; a weak grip of 0.08 rad ~0.7 N).
FORCE_SHARE = 0.75
#: Gain of the squeeze integrator [rad/s per unit of relative margin or force error].
SQUEEZE_GAIN = 1.0
#: Closing rate of a pinch with a pad off the pen after the close phase [rad/s].
CLOSE_RATE = 1.0
#: The slip reflex: below this grasp margin the pads slide on the pen (1 is the cones'
#: boundary, where MuJoCo's sliding contacts sit) [-] ...
SLIP_MARGIN = 1.02
#: ... and the pinch then closes at this rate [rad/s] while the lift loads the grasp (a human
#: grip's slip reflex raises the grip force within ~0.1 s of a slip) ...
SLIP_RATE = 0.75
#: ... and at this rate during the skill's own motion, where unimpaired grips slip briefly too.
SLIP_RATE_SKILL = 0.3
#: The pinch's opening against the library's joint template is estimated over this window
#: of episode time [s] (the hold before the lift: the pinch is closed and every skill's
#: template is the same pinch-lift) ...
OPENING_WINDOW = (SKILL_TIMINGS.close - SKILL_TIMINGS.reach + 0.1, SKILL_TIMINGS.hold - SKILL_TIMINGS.reach)
#: ... and the part of it up to this is a person's own pinch (unimpaired persons p1-p8 lie
#: within -0.037..+0.029 rad of the template), not closed by the assistant [rad].
OPENING_DEADBAND = 0.03
#: Episode time at which the lift ends and the skill's motion may begin [s].
LIFT_END = SKILL_TIMINGS.lift - SKILL_TIMINGS.reach
#: Largest closing offset [rad].
MAX_SQUEEZE = 0.35
#: Episode time after which the pinch is closed and the squeeze is regulated [s] (the close
#: phase of the skills' pinch-lift lasts SKILL_TIMINGS.close - .reach = 0.7 s).
SQUEEZE_FROM = SKILL_TIMINGS.close - SKILL_TIMINGS.reach
#: Largest lag the estimator reports [s].
MAX_LAG = 0.3
#: Samples of the wrist's filtered motion the lag's extrapolation fits (15 = 150 ms).
EXTRAPOLATION_WINDOW = 15
#: Order of the polynomial the lag's extrapolation fits (1: the velocity; 2 was noisier).
EXTRAPOLATION_ORDER = 1
#: Lags below this are not compensated [s]: the estimator's spread on unimpaired operators
#: (their hands differ from the nominal one the protocol time is computed for).
LAG_DEADBAND = 0.04
#: The wrist's extension in the protocol's lift [rad] (ReachPinchLift's lifted pose).
LIFT_EXTENSION = 0.3
#: Gain of the height integrator on the wrist's flexion [rad/s per m of height error].
HEIGHT_GAIN = 40.0
#: Height errors up to this are the person's own way of lifting, not corrected [m].
HEIGHT_DEADBAND = 0.003
#: Largest wrist offset of the height correction [rad].
MAX_HEIGHT_OFFSET = 0.3
#: Episode time from which the pen's height follows the template [s] (the middle of the lift).
HEIGHT_FROM = 0.5 * (SKILL_TIMINGS.hold + SKILL_TIMINGS.lift) - SKILL_TIMINGS.reach
#: Column of the glove observation with the pen's height above its start.
_OBS_HEIGHT = 22


@dataclass(frozen=True)
class SkillTemplate:
    """One skill's stored model as the assistant uses it.

    Attributes:
        name: the skill.
        time: ``(T,)`` episode time of the template [s], its skill starting at ``start``.
        theta: ``(T, 10)`` the mean joint angles of the demonstrations [rad].
        start: the template's skill start [s].
        margin: the median grasp margin of the demonstrations from their skill start [-].
        height: ``(T,)`` the mean height of the pen above its start [m] (the object
            trajectory's vertical part).
        force: the median pinch force of the demonstrations from their skill start (sum
            of the pads' normal intensities) [N].
    """

    name: str
    time: FloatArray
    theta: FloatArray
    start: float
    margin: float
    height: FloatArray
    force: float

    def height_at(self, tau: float) -> float:
        """The pen's height above its start at template time ``tau`` [m]."""
        return float(np.interp(tau, self.time, self.height))

    def at(self, tau: float) -> FloatArray:
        """``(10,)`` joint angles at template time ``tau`` [s] (linear interpolation, held
        at the ends)."""
        out: FloatArray = np.array(
            [np.interp(tau, self.time, self.theta[:, j]) for j in range(N_JOINTS)]
        )
        return out


def load_templates(db_path: str | Path | None = None) -> dict[str, SkillTemplate]:
    """The templates of every glove skill in a library (default: the shipped one).

    Each skill's demonstrations are aligned at their skill start and averaged.

    Args:
        db_path: a skill database (read-only).

    Returns:
        ``{skill name: template}`` for the glove skills the library holds.

    Raises:
        InputError: the file does not exist, or holds no glove skill.
    """
    path = Path(db_path) if db_path is not None else shipped_skill_db()
    if not path.is_file():
        raise InputError(f"skill library {path} does not exist (give an existing --db)")
    groups: dict[str, list[tuple[FloatArray, FloatArray, float, float, FloatArray, float]]] = {}
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            if skill.name not in SKILLS or skill.person_id is None:
                continue
            model = skill.model
            k = skill_start_index(skill)
            margins = demonstrated_margin(skill)[k:]
            finite = margins[np.isfinite(margins)]
            margin = float(np.median(np.minimum(finite, 10.0))) if finite.size else 1.2
            start = skill_start_time(skill.name, skill.person_id)
            obs = np.asarray(skill.demonstration.observations, dtype=np.float64)
            per = model.c.shape[1] // model.touching.shape[1]
            normal = np.nan_to_num(np.asarray(model.c)[:, ::per]).sum(axis=1)
            groups.setdefault(skill.name, []).append(
                (
                    np.asarray(model.time, dtype=np.float64),
                    obs[:, :N_JOINTS],
                    start,
                    margin,
                    obs[:, _OBS_HEIGHT],
                    float(np.median(normal[k:])),
                )
            )
    if not groups:
        raise InputError(f"skill library {path} holds no glove skill ({', '.join(SKILLS)})")
    out = {}
    for name, demos in groups.items():
        start = float(np.mean([d[2] for d in demos]))
        time = demos[0][0]
        # every demonstration shifted so that its skill starts at the mean start
        theta = np.mean(
            [
                np.stack(
                    [np.interp(time + d[2] - start, d[0], d[1][:, j]) for j in range(N_JOINTS)], 1
                )
                for d in demos
            ],
            axis=0,
        )
        height = np.mean([np.interp(time + d[2] - start, d[0], d[4]) for d in demos], axis=0)
        margin = float(np.median([d[3] for d in demos]))
        force = float(np.median([d[5] for d in demos]))
        out[name] = SkillTemplate(name, time, theta, start, margin, height, force)
    return out


class OracleRecogniser:
    """A recogniser that knows the intent (the recogniser protocol of issue #14).

    Args:
        intent: episode time [s] -> the intended skill (e.g. the env's ``intent``).
        skills: the skills it names.
    """

    def __init__(self, intent: Callable[[float], str], skills: Sequence[str] = SKILLS) -> None:
        self.intent = intent
        self._skills = tuple(skills)

    @property
    def skills(self) -> tuple[str, ...]:
        """The skills it knows."""
        return self._skills

    def reset(self) -> None:
        """Nothing to forget."""

    def update(self, frame: Any) -> dict[str, float]:
        """Posterior 1 on the intent at ``frame.time_s`` (``"unknown"`` if not a known skill)."""
        truth = self.intent(float(frame.time_s))
        post = dict.fromkeys((*self._skills, "unknown"), 0.0)
        post[truth if truth in self._skills else "unknown"] = 1.0
        return post

    def add_skill(self, name: str, sessions: Sequence[Sequence[Any]]) -> None:
        """Know ``name`` from now on (the oracle needs no sessions)."""
        if name not in self._skills:
            self._skills = (*self._skills, name)


def _session_frame(env: Any) -> SessionFrame:
    return frames_from_env(env)


def live_margin(env: Any) -> float:
    """The grasp margin of the pen's pinch now [-] (NaN unless both pads touch).

    Args:
        env: an unwrapped glove env after ``reset`` or ``step``.
    """
    from ias_gym.sim.glove_contacts import pinch_null_basis  # MuJoCo scene code

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
    return grasp_margin(c - c_h, c_h, GLOVE_PEN_MU, GLOVE_PAD_TORSION, 4)


def protocol_half_lift_time(control_dt: float, filter_tau: float) -> float:
    """Episode time [s] at which the protocol's lift, seen through the env's low-pass, has
    extended the wrist by half of :data:`LIFT_EXTENSION`, with readings on time."""
    script = ReachPinchLift(PersonParams.nominal(), SKILL_TIMINGS)
    wf = joint_index("wrist_flexion")
    alpha = control_dt / (filter_tau + control_dt)
    start = SKILL_TIMINGS.reach
    y = float(script(start)[wf])
    hold = float(script(SKILL_TIMINGS.hold)[wf])
    k = 0
    while k < 10_000:
        k += 1
        y += alpha * (float(script(start + k * control_dt)[wf]) - y)
        if y <= hold - 0.5 * LIFT_EXTENSION:
            return k * control_dt
    raise ValueError("the protocol's lift never reaches half its extension")


class AnalyticAssistant:
    """Complete the recognised skill from its stored model (module docstring).

    Args:
        templates: the library's templates (:func:`load_templates`).
        recogniser: gives the posterior (the recogniser protocol); None: an
            :class:`OracleRecogniser` on the env's intent, made at every :meth:`reset`.
        tremor_filter, lag_compensation, squeeze, height: switch the four terms (ablations;
            the lag compensation is off by default: it made held-out sessions worse,
            docs/assistance.md).
    """

    def __init__(
        self,
        templates: dict[str, SkillTemplate],
        recogniser: Any = None,
        *,
        tremor_filter: bool = True,
        lag_compensation: bool = False,
        squeeze: bool = True,
        height: bool = True,
    ) -> None:
        self.templates = templates
        self.recogniser = recogniser
        self._oracle = recogniser is None
        self.tremor_filter = tremor_filter
        self.lag_compensation = lag_compensation
        self.squeeze = squeeze
        self.height = height
        self.h = 0.0
        self._tremor_idx = np.array([joint_index(j) for j in TREMOR_JOINTS])
        self._wf = JOINT_NAMES.index("wrist_flexion")
        self._pinch = pinch_direction()
        self._post: dict[str, float] = {}
        self.lag_s = 0.0
        self.g = 0.0

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
        sos = butter(2, TREMOR_STOP, btype="bandstop", fs=1.0 / self._dt, output="sos")
        self._sos = sos
        theta = self._operator_theta(env)
        self._zi = sosfilt_zi(sos)[:, :, None] * theta[self._tremor_idx][None, None, :]
        self._half_lift = protocol_half_lift_time(self._dt, float(cfg.filter_tau))
        self._hold_wf: float | None = None
        self._lag_known = False
        self.lag_s = 0.0
        self.g = 0.0
        self.h = 0.0
        self._openings: list[float] = []
        self.opening = 0.0
        self._person_start = skill_start_time(
            str(cfg.skill) if cfg.skill else SKILLS[0], env.person.person_id
        )
        self._post = {}
        self._history: deque[FloatArray] = deque(maxlen=EXTRAPOLATION_WINDOW)

    @staticmethod
    def _operator_theta(env: Any) -> FloatArray:
        upcoming = getattr(env, "upcoming_theta", None)
        return np.array(env._theta if upcoming is None else upcoming, dtype=np.float64)

    def posterior(self) -> dict[str, float]:
        """The recogniser's posterior of the last :meth:`act`."""
        return dict(self._post)

    def _extrapolate(self, ahead: float) -> FloatArray:
        """The wrist's motion over the next ``ahead`` [s]: a quadratic fitted (least squares)
        to its last :data:`EXTRAPOLATION_WINDOW` filtered samples, evaluated ``ahead`` past
        the newest minus its value there."""
        y = np.asarray(self._history)
        n = len(y)
        x = (np.arange(n) - (n - 1)) * self._dt
        coef = np.polyfit(x, y, EXTRAPOLATION_ORDER)
        out: FloatArray = np.polyval(coef, ahead) - coef[-1]
        return out

    def _template_time(self, template: SkillTemplate, t: float) -> float:
        """Template time of the operator's intent at episode time ``t`` [s]."""
        if t < self._person_start:
            return t
        return t - self._person_start + template.start

    def _estimate_lag(self, t: float, wf: float) -> None:
        if self._lag_known:
            return
        if t < SKILL_TIMINGS.hold - SKILL_TIMINGS.reach - 0.05:
            self._hold_wf = wf  # the pinch held before the lift
            return
        if self._hold_wf is not None and wf <= self._hold_wf - 0.5 * LIFT_EXTENSION:
            self.lag_s = float(min(max(t - self._half_lift, 0.0), MAX_LAG))
            self._lag_known = True

    def act(self, env: Any) -> FloatArray:
        """The offsets ``(10,)`` (in action units, clipped to [-1, 1]) for the next step."""
        t = (env._steps + 1) * self._dt  # time of the reading the hand gets next
        theta = self._operator_theta(env)
        post = self.recogniser.update(_session_frame(env))
        self._post = dict(post)
        offset = np.zeros(N_JOINTS)
        filtered = theta.copy()
        if self.tremor_filter:
            y, self._zi = sosfilt(self._sos, theta[self._tremor_idx][None, :], axis=0, zi=self._zi)
            filtered[self._tremor_idx] = y[0]
            offset += filtered - theta
        self._estimate_lag(t, float(filtered[self._wf]))
        self._history.append(filtered[list(WRIST_JOINTS)])
        if self.lag_compensation and self.lag_s > LAG_DEADBAND and len(self._history) >= 3:
            offset[list(WRIST_JOINTS)] += self._extrapolate(self.lag_s)
        if self.squeeze and OPENING_WINDOW[0] <= t <= OPENING_WINDOW[1]:
            template = next(iter(self.templates.values()))  # the shared pinch-lift
            d = self._pinch
            self._openings.append(float(d @ (template.at(t) - theta) / (d @ d)))
            self.opening = max(float(np.mean(self._openings)) - OPENING_DEADBAND, 0.0)
        if self.squeeze and t >= SQUEEZE_FROM:
            known = [m.margin for m in self.templates.values()]
            forces = [m.force for m in self.templates.values()]
            target = MARGIN_FACTOR * sum(
                p * (self.templates[k].margin if k in self.templates else float(np.median(known)))
                for k, p in post.items()
            )
            force = sum(
                p * (self.templates[k].force if k in self.templates else float(np.median(forces)))
                for k, p in post.items()
            )
            m = live_margin(env)
            if math.isnan(m):
                self.g += CLOSE_RATE * self._dt
            else:
                # the margin, and before the lift (the support carries the pen, the margin
                # says nothing) the pinch force against the library's
                err_m = (target - min(m, 2.0 * target)) / target
                # a person's own squeeze differs from the library's by tens of percent:
                # only a clearly weaker one (below FORCE_SHARE of it) is a weak grip
                err_f = (FORCE_SHARE * force - min(float(env._pinch_force), force)) / force
                self.g += SQUEEZE_GAIN * max(err_m, err_f) * self._dt
                if m < SLIP_MARGIN:
                    self.g += (SLIP_RATE if t <= LIFT_END else SLIP_RATE_SKILL) * self._dt
            self.g = float(min(max(self.g, self.opening), MAX_SQUEEZE))
            offset += self.g * self._pinch
        if self.height and t >= HEIGHT_FROM:
            z_t = sum(
                p * self.templates[k].height_at(self._template_time(self.templates[k], t))
                for k, p in post.items()
                if k in self.templates
            )
            weight = sum(p for k, p in post.items() if k in self.templates)
            err = z_t - weight * float(env.data.xpos[env._pen_body][2] - env._pen_start[2])
            err = math.copysign(max(abs(err) - HEIGHT_DEADBAND, 0.0), err)
            self.h = float(
                np.clip(
                    self.h + HEIGHT_GAIN * err * self._dt, -MAX_HEIGHT_OFFSET, MAX_HEIGHT_OFFSET
                )
            )
            offset[self._wf] -= self.h  # extension (-) lifts the pen
        out: FloatArray = np.clip(offset / self._scale, -1.0, 1.0)
        return out
