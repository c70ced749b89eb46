"""The observation assistant's completion of one skill, and its fitted thresholds.

:class:`Completion` fits an operator's version of a library skill's motion
(:class:`~ias_gym.assist.skill_motions.SkillMotion`) to what they have done since the motion
set in, tests whether they have stopped short of it and then drives the skill's principal
joint the rest of the way (:mod:`ias_gym.assist.policy`'s docstring, step 2).
:class:`AssistParams` are the thresholds ``train/fit_assistant.py`` fits.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym.assist.skill_motions import SkillMotion
from ias_gym.errors import InputError
from ias_gym.outputs import atomic_output

FloatArray = NDArray[np.float64]

#: Where the fitted parameters are stored (``train/fit_assistant.py`` writes it).
PARAMS_PATH = Path(__file__).resolve().parents[1] / "assets" / "assistant_params.json"
#: The grids the operator's speed and start are fitted on: speeds relative to the
#: library's mean person [-] (the population's speed factors lie within 0.6-1.6) ...
SPEED_GRID = np.linspace(0.6, 1.6, 21)
#: ... and starts relative to the detected onset [s], on either side of it: an unsteady
#: operator's wrist can leave its pose by ``onset_rad`` a few tenths of a second before the
#: motion begins (a drift, an anticipatory dip), and a fit whose start could not follow the
#: motion there took a slower, larger motion for it.
START_GRID = np.arange(-0.3, 0.32, 0.02)
#: The operator's motion is refitted every this many steps (between them the last fit
#: predicts; a fit costs about a millisecond).
REFIT_EVERY = 5
#: How far ahead the model's motion still to go is looked for [s] (the longest skill motion
#: of the slowest person).
FUTURE_S = 3.0
#: The fit reads the operator's motion up to this many stop windows back: a stop shows
#: in the test only once the window is past it and the env's low-pass on the operator's
#: targets has settled, and samples from after a stop are no evidence of the motion meant.
FIT_LAG = 2
#: The least unsteadiness of an operator the fit assumes [rad]: about the smallest
#: physiological tremor of a wrist (docs/population.md, ``tremor_amplitude``).
NOISE_FLOOR = 1e-3


@dataclass(frozen=True)
class AssistParams:
    """The assistant's fitted thresholds (``train/fit_assistant.py``).

    Attributes:
        onset_rad: the skill's motion has set in once a moving joint left its pose at the
            lift's end by this much [rad] (``train/fit_assist_field.py``).
        stop_window_s: the window over which the operator's and the model's speeds are
            compared [s].
        stop_ratio: the operator is slowing down when their speed over the window is below
            this share of the fitted model's [-] ...
        stop_hold_s: ... and has stopped when that has lasted this long [s] (0: at the first
            slow window; ``train/fit_assist_field.py``).
        min_model_speed: ... and the model's is at least this [rad/s] (a model at a turning
            point says nothing).
        min_remaining_rad: ... and the model still moves at least this far from its pose now
            [rad] (a person who ends a motion early is not stopped).
        tremor_window_s: when the tremor canceller's notch starts and how often it is
            retuned [s] (:class:`~ias_gym.assist.tremor.TremorCanceller`;
            ``train/fit_assist_field.py``).
        tremor_trend_degree: the degree of the polynomial the canceller fits beside the
            tremor's line, the voluntary motion's part of its window [-]
            (:func:`~ias_gym.assist.tremor.sinusoid_line`; ``train/fit_assist_field.py``).
        tremor_floor_rad: the least amplitude of a line of the tremor band that the
            canceller takes for a tremor [rad]; 0: no detection, every line is notched
            (:class:`~ias_gym.assist.tremor.TremorCanceller`; ``train/fit_assist_field.py``).
        sight_gain: once a completed motion is done, the rate [1/s] at which the assistant
            brings the pen to where the operator's version of the skill leaves it, as the
            person would by sight: its height to the demonstrations'
            (:attr:`~ias_gym.assist.skill_motions.SkillMotion.goal_height`) through the
            wrist flexion, its axis to the operator's tilt through the pronation; each joint
            moves by ``sight_gain x`` its error per second, in radians through the
            demonstrations' ``rise_per_flexion`` and ``tilt_per_pronation``
            (``train/fit_assist_field.py``).
        catch_up_pace: once a stop is latched, the completion resumes the fitted motion from
            where the operator stopped and runs it at this multiple of its pace until it is
            back on the fitted timeline [-] (1: it stays as late as the latch; large: a jump
            toward where the operator would be by now; ``train/fit_assist_field.py``).
        pad_close_rate: how fast a finger whose pad is off the pen, while the other's is on,
            is closed [rad/s] (:class:`~ias_gym.assist.pad_contact.PadKeeper`;
            ``train/fit_assist_field.py``).
        fitted_on: what the values were fitted on (persons' seed and count), for the record.
    """

    onset_rad: float = 0.01
    stop_window_s: float = 0.1
    stop_ratio: float = 0.3
    stop_hold_s: float = dataclasses.field(default=0.1, metadata={"zero_switches_off": True})
    min_model_speed: float = 0.05
    min_remaining_rad: float = 0.05
    tremor_window_s: float = 0.5
    tremor_trend_degree: int = 1
    tremor_floor_rad: float = dataclasses.field(default=0.0, metadata={"zero_switches_off": True})
    sight_gain: float = 3.0
    catch_up_pace: float = 2.0
    pad_close_rate: float = 0.5
    fitted_on: str = "defaults"

    @classmethod
    def integer_fields(cls) -> frozenset[str]:
        """The fields that take whole numbers (declared ``int``)."""
        return frozenset(f.name for f in dataclasses.fields(cls) if f.type in (int, "int"))

    @classmethod
    def may_be_zero(cls) -> frozenset[str]:
        """The fields a 0 switches off (marked ``zero_switches_off`` in their metadata)."""
        return frozenset(
            f.name for f in dataclasses.fields(cls) if f.metadata.get("zero_switches_off")
        )

    @classmethod
    def load(cls, path: str | Path = PARAMS_PATH) -> AssistParams:
        """Read the parameters from a JSON file (plain data: nothing executes).

        Raises:
            InputError: the file is missing, not JSON, or has unknown or non-numeric keys.
        """
        p = Path(path)
        try:
            data = json.loads(p.read_text())
        except FileNotFoundError:
            raise InputError(
                f"assistant parameters {p} do not exist (run train/fit_assistant.py)"
            ) from None
        except (OSError, ValueError) as e:
            raise InputError(f"assistant parameters {p} are unreadable: {e}") from None
        fields = {f.name for f in dataclasses.fields(cls)}
        if not isinstance(data, dict) or not set(data) <= fields:
            raise InputError(f"assistant parameters {p}: keys must be among {sorted(fields)}")
        integers = cls.integer_fields()
        for key, value in data.items():
            if key == "fitted_on":
                ok = isinstance(value, str)
            elif key in integers:
                ok = isinstance(value, int) and not isinstance(value, bool) and value >= 1
            elif key in cls.may_be_zero():
                ok = _positive(value) or value == 0
            else:
                ok = _positive(value)
            if not ok:
                raise InputError(f"assistant parameters {p}: {key}={value!r} is not valid")
        return cls(**data)

    def save(self, path: str | Path = PARAMS_PATH, *, overwrite: bool = False) -> None:
        """Write the parameters as JSON, atomically (an existing file only with
        ``overwrite``)."""
        with atomic_output(path, overwrite=overwrite) as tmp:
            tmp.write_text(json.dumps(dataclasses.asdict(self), indent=2) + "\n")


def _positive(value: object) -> bool:
    return isinstance(value, int | float) and math.isfinite(value) and value > 0


def _slope(t: FloatArray, y: FloatArray) -> float:
    """The least-squares slope of ``y`` over ``t``."""
    dt = t - t.mean()
    return float((dt * (y - y.mean())).sum() / max(float((dt * dt).sum()), 1e-12))


class Completion:
    """One skill's fit of the operator's motion and its completion (module docstring, 2)."""

    def __init__(self, motion: SkillMotion, params: AssistParams, dt: float) -> None:
        self.motion, self.params, self.dt = motion, params, dt
        self.times: list[float] = []
        self.values: list[FloatArray] = []  # operator's joints less their pose at LIFT_END
        self.onset: float | None = None
        self.fit: tuple[float, float, float] | None = None  # (a, v, t0)
        self.noise: float | None = None  # the operator's unsteadiness before the onset [rad]
        self.stopped_at: float | None = None
        self.slow_since: float | None = None  # the stop test holds since then [s]
        self._failing_s = 0.0  # ... and has failed for this long since it last held [s]
        self._clock = 0.0  # the completion's time on the fitted timeline [s]

    @property
    def motion_done(self) -> bool:
        """A stop is latched and the completion has come to the end of the fitted motion
        (:attr:`~ias_gym.assist.skill_motions.SkillMotion.end_tau` on its timeline)."""
        if self.stopped_at is None or self.fit is None:
            return False
        _, v, t0 = self.fit
        return self._clock >= t0 + self.motion.end_tau / v

    def model(self, t: NDArray[Any]) -> FloatArray:
        """``(len(t), J)`` the fitted motion at episode times ``t``."""
        assert self.fit is not None
        a, v, t0 = self.fit
        return a * self.motion.at(v * (np.asarray(t) - t0))

    def _refit(self, n: int) -> None:
        """Fit ``(a, v, t0)`` to the first ``n`` samples: the most probable under the
        library's spread of persons (:attr:`SkillMotion.amplitude_sd`,
        :attr:`SkillMotion.speed_sd`) and the operator's own unsteadiness before the
        motion (:attr:`noise`), ``a`` in closed form for each ``(v, t0)`` of the grids.

        Early in a motion its amplitude and speed are hardly told apart (a minimum-jerk
        start grows as ``a v^3``); the library's spread decides between them."""
        assert self.onset is not None
        t = np.asarray(self.times[:n])
        y = np.asarray(self.values[:n])  # (N, J)
        if self.noise is None:
            still = y[t < self.onset]
            spread = float(np.sqrt(np.mean((still - still.mean(axis=0)) ** 2))) if len(still) else 0
            self.noise = max(spread, NOISE_FLOOR)
        wa = (self.noise / max(self.motion.amplitude_sd, 1e-3)) ** 2  # prior weights, in
        wv = (self.noise / max(self.motion.speed_sd, 1e-3)) ** 2  # units of the residual
        best = (math.inf, (1.0, 1.0, self.onset))
        for t0 in self.onset + START_GRID:
            tau = SPEED_GRID[:, None] * (t[None, :] - t0)  # (V, N)
            m = self.motion.at(tau.ravel()).reshape(len(SPEED_GRID), len(t), -1)
            mm = (m * m).sum(axis=(1, 2))
            my = (m * y[None]).sum(axis=(1, 2))
            a = (my + wa) / (mm + wa)
            res = ((a[:, None, None] * m - y[None]) ** 2).sum(axis=(1, 2))
            cost = res + wa * (a - 1.0) ** 2 + wv * np.log(SPEED_GRID) ** 2
            i = int(np.argmin(cost))
            if cost[i] < best[0]:
                best = (float(cost[i]), (float(a[i]), float(SPEED_GRID[i]), float(t0)))
        self.fit = best[1]

    def update(self, t: float, value: FloatArray, refit: bool) -> FloatArray:
        """Take the operator's joints (less their pose at the lift's end) at ``t``; return
        the completion's offset on the skill's joints (zero until a stop is latched).

        The stop test: the model fitted to what the operator did before the last
        ``stop_window_s`` predicts the window; the operator moved less than ``stop_ratio``
        of it. From the first such window on the fit is held (what the operator does while
        slowing down is no evidence of how they meant to move), and the stop is latched
        once the test has held for ``stop_hold_s`` (a turning point or a hesitation of an
        unimpaired operator passes sooner). It is reset once it has failed for a window:
        a stopped wrist's unsteadiness lifts the operator's speed over the ratio for a
        step or two, and a fit made then would read the samples after the stop as a
        small motion already over."""
        p = self.params
        if self.stopped_at is None:
            self.times.append(t)
            self.values.append(value)
            if self.onset is None and float(np.abs(value).max()) > p.onset_rad:
                self.onset = t
            w = round(p.stop_window_s / self.dt)
            if self.onset is None or t - self.onset < (FIT_LAG + 1) * p.stop_window_s:
                return np.zeros(len(self.motion.joints))
            if self.slow_since is None and (refit or self.fit is None):
                self._refit(len(self.times) - FIT_LAG * w)
            # on the skill's principal joint (its largest motion): the others carry what the
            # demonstrating persons corrected on the way, which another person need not
            j = self.motion.principal
            # speeds as least-squares slopes over the window's samples: the operator's
            # tremor averages out without delaying the test
            ts = np.asarray(self.times[-1 - w :])
            model_speed = abs(_slope(ts, self.model(ts)[:, j]))
            op_speed = abs(_slope(ts, np.asarray(self.values[-1 - w :])[:, j]))
            ahead = self.model(t + np.arange(0.0, FUTURE_S, 0.05))[:, j]
            remaining = float(np.abs(ahead - value[j]).max())  # from where the operator is
            armed = model_speed >= p.min_model_speed and remaining >= p.min_remaining_rad
            holds = armed and op_speed < p.stop_ratio * model_speed
            # the test is reset as it is latched: only once it has failed for a window (a
            # stopped wrist's unsteadiness lifts its speed over the ratio for a step or two)
            self._failing_s = 0.0 if holds else self._failing_s + self.dt
            if self._failing_s >= p.stop_window_s - 0.5 * self.dt:
                self.slow_since = None
            elif holds:
                if self.slow_since is None:
                    self.slow_since = t
                if t - self.slow_since >= p.stop_hold_s - 0.5 * self.dt:
                    self.stopped_at = t
                    # when the operator stopped: the model's pose nearest to theirs since
                    # the slowing down began
                    grid = np.arange(self.slow_since - 2.0 * p.stop_window_s, t, self.dt)
                    gap = np.abs(self.model(grid) - value).max(axis=1)
                    self._clock = float(grid[int(np.argmin(gap))])
        if self.stopped_at is None:
            return np.zeros(len(self.motion.joints))
        # resume from where the operator stopped and catch up with the fitted timeline at
        # catch_up_pace times its pace (no step in the targets)
        self._clock = min(self._clock + p.catch_up_pace * self.dt, t)
        out: FloatArray = np.zeros(len(self.motion.joints))
        j = self.motion.principal
        out[j] = self.model(np.array([self._clock], dtype=np.float64))[0, j] - value[j]
        return out
