"""Tremor cancelling on the operator's joint targets, from the targets alone.

Pathological tremors lie at 4-12 Hz (parkinsonian rest tremor 4-6 Hz, essential tremor
4-12 Hz: Deuschl, Bain & Brin 1998); voluntary hand motion lies below about 2 Hz (the
fastest skill, the fast see-saw, at 1.5 Hz). :class:`TremorCanceller` removes the strongest
spectral line of the tremor band from the targets, without knowing the tremor's frequency,
which joints shake or whether the operator has a tremor at all:

1. **The line.** Over the last :data:`FREQUENCY_WINDOW_S` of the targets (at first, what
   there is of it), the sinusoid that explains them best beside a polynomial on each joint
   (the voluntary motion's part; its degree is fitted by ``train/fit_assist_field.py --field
   tremor_trend_degree``), one frequency for all joints (:func:`sinusoid_line`: least
   squares on a grid of frequencies). A short window holds under a cycle of a slow tremor at
   first (0.2 s of a 4 Hz one), and a spectrum's peak is then wide and pulled away by the
   voluntary motion: at 4-5 Hz the spectral estimate of the first windows was 1-2 Hz off,
   and the pinch closed with the tremor in it. Fitting the sinusoid with the motion's trend
   finds it within a few tenths of a hertz from the first window on (Stoica & Moses,
   *Spectral Analysis of Signals*, 2005, ch. 4: the least-squares frequency of a sinusoid).
   Where the best frequency is the search's lowest, the window holds a curve, not a line (a
   fast close of the fingers), and the line is the spectral peak of the targets through a
   causal high-pass instead (Butterworth of order :data:`HIGHPASS_ORDER` at
   :data:`HIGHPASS_HZ`, between the two bands; :func:`tremor_line`: Hann window,
   zero-padded, summed over the joints, a parabola through the peak's log power).
2. **Cancelling.** From the first ``window_s`` of the session on, a second-order notch
   (scipy's ``iirnotch``) at the line's frequency on every joint, started at rest on the
   current targets and retuned every ``window_s`` (its state kept); the canceller's offset
   is the notched targets less the targets. ``window_s`` is fitted by
   ``train/fit_assist_field.py`` (:class:`~ias_gym.assist.motion_completion.AssistParams`).

3. **Detection** (``floor_rad`` > 0). The offset is applied only while the line, at its
   last retune, is at least ``floor_rad`` strong (the norm over the joints): a tremor's line
   is strong, the line an operator without one shows is weak. The notch runs on in between,
   its state kept, so that a line that grows again is cancelled at once. ``floor_rad`` is
   fitted by ``train/fit_assist_field.py --field tremor_floor_rad`` against unimpaired,
   lagged and tremor sessions together; 0 switches detection off. Asking the line to stay at
   one frequency over two retunes as well was measured and not kept: in a window still
   filling, a strong tremor's frequency estimate moves by more than a notch's tolerance, and
   the notch started 0.2-0.4 s later, after the pinch had closed with the tremor in it.

Without detection an operator without a tremor gets the notch too, at whatever line their
targets have. What that costs is the notch's phase lag on their voluntary motion, bounded
by its width :data:`NOTCH_WIDTH_HZ`: at most 15 deg at 1.5 Hz under a 4 Hz notch
(:func:`notch_phase_deg`; about 25 ms), less for higher ones.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, iirnotch, sosfilt, sosfilt_zi, tf2sos

FloatArray = NDArray[np.float64]

#: The pathological tremors' band [Hz] (module docstring).
TREMOR_BAND = (4.0, 12.0)
#: The high-pass [Hz] and its order: 8th order at 3 Hz takes a 1.5 Hz voluntary motion
#: down 48 dB and passes a 4 Hz tremor whole.
HIGHPASS_HZ = 3.0
HIGHPASS_ORDER = 8
#: The window the line is found in [s]: the sinusoid fit's, and the spectrum's (whose Hann
#: main lobe is then +-2 Hz wide).
FREQUENCY_WINDOW_S = 1.0
#: The notch's -3 dB width [Hz]: lags a 1.5 Hz motion by 12 deg under a 4 Hz notch.
NOTCH_WIDTH_HZ = 2.0
#: Zero-padded length of the spectrum.
SPECTRUM_N = 1024
#: The frequencies the sinusoid is fitted at [Hz]: the band widened by 1 Hz each side
#: (a best fit at the lowest is a trend, not a line), in steps of 0.05 Hz.
FIT_GRID_HZ = np.arange(TREMOR_BAND[0] - 1.0, TREMOR_BAND[1] + 1.0 + 1e-9, 0.05)


def notch_phase_deg(f_hz: float, notch_hz: float, width_hz: float = NOTCH_WIDTH_HZ) -> float:
    """The phase [deg] the continuous notch at ``notch_hz`` (-3 dB width ``width_hz``) adds
    at ``f_hz`` below it (negative: a lag)."""
    w, w0, q = f_hz, notch_hz, notch_hz / width_hz
    return -math.degrees(math.atan2(w * w0 / q, w0 * w0 - w * w))


def tremor_line(window: FloatArray, dt: float) -> tuple[float, float]:
    """``(frequency [Hz], amplitude [rad])`` of the strongest spectral line of ``window``
    ``(N, joints)`` (sampled every ``dt``) within the tremor band (widened by 1 Hz for the
    search, the frequency clipped to the band): the peak of the Hann window's zero-padded
    spectrum summed over the joints, refined by a parabola through the peak's log power;
    the amplitude is the norm over the joints of each joint's sinusoid there
    (``2 |X| / sum(w)``: a sinusoid of amplitude ``A`` on one joint gives ``A``)."""
    hann = np.hanning(len(window))
    spec = np.abs(np.fft.rfft(window * hann[:, None], SPECTRUM_N, axis=0))
    power = np.sum(spec**2, axis=1)
    freqs = np.fft.rfftfreq(SPECTRUM_N, dt)
    band = np.flatnonzero((freqs >= TREMOR_BAND[0] - 1.0) & (freqs <= TREMOR_BAND[1] + 1.0))
    k = int(band[np.argmax(power[band])])
    a, b, c = np.log(power[k - 1 : k + 2] + 1e-300)
    k_off = 0.5 * (a - c) / (a - 2 * b + c) if a - 2 * b + c < 0 else 0.0
    f = float(np.clip(freqs[k] + k_off * (freqs[1] - freqs[0]), *TREMOR_BAND))
    return f, 2.0 * math.sqrt(float(power[k])) / float(hann.sum())


def sinusoid_line(window: FloatArray, dt: float, degree: int = 1) -> tuple[float, float] | None:
    """``(frequency [Hz], amplitude [rad])`` of the sinusoid that, beside a polynomial of
    ``degree`` (:func:`trend_basis`) on each joint, explains ``window`` ``(N, joints)``
    (sampled every ``dt``) best in least squares, one frequency for all joints: the least
    residual over :data:`FIT_GRID_HZ`, refined by a parabola through it, clipped to the
    band; the amplitude is the norm over the joints of each joint's sinusoid. None when the
    least residual is at the grid's lowest frequency: the window holds a curve of the
    voluntary motion, not a line."""
    n = len(window)
    t = np.arange(n) * dt
    y = np.asarray(window, dtype=np.float64)
    trend = trend_basis(n, dt, degree)
    phase = 2 * np.pi * FIT_GRID_HZ[:, None] * t[None, :]  # (F, n)
    x = np.concatenate(
        [
            np.broadcast_to(trend, (len(FIT_GRID_HZ), *trend.shape)),
            np.sin(phase)[:, :, None],
            np.cos(phase)[:, :, None],
        ],
        axis=2,
    )  # (F, n, K): every frequency's design at once
    xty = np.einsum("fnk,nj->fkj", x, y)
    coef = np.linalg.solve(np.einsum("fnk,fnl->fkl", x, x), xty)  # (F, K, J)
    costs = float(np.sum(y * y)) - np.einsum("fkj,fkj->f", xty, coef)  # residual sums
    k = int(np.argmin(costs))
    if k == 0:
        return None
    step = float(FIT_GRID_HZ[1] - FIT_GRID_HZ[0])
    offset = 0.0
    if k < len(costs) - 1:
        a, b, c = costs[k - 1 : k + 2]
        offset = 0.5 * (a - c) / (a - 2 * b + c) if a - 2 * b + c > 0 else 0.0
    f = float(np.clip(FIT_GRID_HZ[k] + offset * step, *TREMOR_BAND))
    design = np.column_stack([trend, np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    amplitudes, *_ = np.linalg.lstsq(design, y, rcond=None)
    return f, float(np.sqrt(np.sum(amplitudes[-2:] ** 2)))


def trend_basis(n: int, dt: float, degree: int) -> FloatArray:
    """``(n, d + 1)``: the Legendre polynomials up to ``d`` (on [-1, 1]: well conditioned)
    over a window of ``n`` samples every ``dt``, the voluntary motion's part of it. ``d`` is
    ``degree``, or 1 in a window shorter than a period of the band's slowest tremor: a
    curve of higher degree takes up part of a slow line that the window holds under a cycle
    of."""
    d = int(degree) if n * dt >= 1.0 / TREMOR_BAND[0] else 1
    basis = np.polynomial.legendre.legvander(np.linspace(-1.0, 1.0, n), d)
    return np.asarray(basis, dtype=np.float64)


class TremorCanceller:
    """The tremor's offset on the operator's targets (module docstring).

    Args:
        dt: the control step [s].
        window_s: when the notch starts and how often it is retuned [s].
        joints: how many joints the targets have.
        trend_degree: the degree of the voluntary motion's polynomial beside the line
            (:func:`sinusoid_line`).
        floor_rad: the least amplitude of a line that counts as a tremor [rad] (module
            docstring, 3.); 0: no detection, every line is notched.

    Raises:
        ValueError: a step too long to see the tremor band, a window shorter than 4 steps,
            or a negative floor.
    """

    def __init__(
        self,
        dt: float,
        window_s: float,
        joints: int = 10,
        trend_degree: int = 1,
        floor_rad: float = 0.0,
    ) -> None:
        self.dt = float(dt)
        self.joints = int(joints)
        self.trend_degree = int(trend_degree)
        self.floor_rad = float(floor_rad)
        if not self.floor_rad >= 0.0:
            raise ValueError(f"a floor of {floor_rad} rad is not >= 0")
        self.window = round(float(window_s) / self.dt)
        fs = 1.0 / self.dt
        if TREMOR_BAND[1] >= fs / 2:
            raise ValueError(
                f"a control step of {dt} s cannot see tremors up to {TREMOR_BAND[1]} Hz"
            )
        if self.window < 4:
            raise ValueError(f"a window of {window_s} s is under 4 control steps of {dt} s")
        self._hp = butter(HIGHPASS_ORDER, HIGHPASS_HZ, btype="highpass", fs=fs, output="sos")
        self.reset()

    def reset(self) -> None:
        """Start a session."""
        self._hp_state: FloatArray | None = None
        n = round(FREQUENCY_WINDOW_S / self.dt)
        self._recent: deque[FloatArray] = deque(maxlen=n)  # the high-passed targets ...
        self._raw: deque[FloatArray] = deque(maxlen=n)  # ... and the targets
        self._since_tuned = 0
        self._notch: FloatArray | None = None
        self._notch_state: FloatArray | None = None
        #: The notch's frequency [Hz] (None before the first window is full) ...
        self.frequency_hz: float | None = None
        #: ... and the line's amplitude there when it was last tuned [rad].
        self.amplitude_rad = 0.0
        #: Whether the offset is applied: the line is strong enough (always, without
        #: detection).
        self.engaged = False

    def update(self, theta: FloatArray) -> FloatArray:
        """Take the operator's targets ``(joints,)`` [rad]; return the offset that cancels
        the tremor band's line in them (zero during the first window)."""
        x = np.asarray(theta, dtype=np.float64)
        if self._hp_state is None:  # start at rest on the first targets: no step response
            self._hp_state = sosfilt_zi(self._hp)[:, :, None] * x[None, None, :]
        hp, self._hp_state = sosfilt(self._hp, x[None, :], axis=0, zi=self._hp_state)
        self._recent.append(hp[0])
        self._raw.append(x.copy())
        self._since_tuned += 1
        if self._since_tuned >= self.window:
            line = sinusoid_line(np.asarray(self._raw), self.dt, self.trend_degree)
            if line is None:
                line = tremor_line(np.asarray(self._recent), self.dt)
            self.frequency_hz, self.amplitude_rad = line
            self.engaged = self.amplitude_rad >= self.floor_rad
            b, a = iirnotch(self.frequency_hz, self.frequency_hz / NOTCH_WIDTH_HZ, fs=1.0 / self.dt)
            self._notch = tf2sos(b, a)
            self._since_tuned = 0
            if self._notch_state is None:
                self._notch_state = sosfilt_zi(self._notch)[:, :, None] * x[None, None, :]
        if self._notch is None or self._notch_state is None:
            return np.zeros(self.joints)
        y, self._notch_state = sosfilt(self._notch, x[None, :], axis=0, zi=self._notch_state)
        if not self.engaged:
            return np.zeros(self.joints)
        out: FloatArray = y[0] - x
        return out
