"""The tremor canceller (ias_gym.assist.tremor) on made-up targets: a voluntary see-saw with
and without a tremor anywhere in the pathological band."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfiltfilt

import ias_gym  # noqa: F401
from ias_gym.assist.policy import make_assistant
from ias_gym.assist.tremor import (
    HIGHPASS_HZ,
    HIGHPASS_ORDER,
    TREMOR_BAND,
    TremorCanceller,
    notch_phase_deg,
    sinusoid_line,
    tremor_line,
    trend_basis,
)
from ias_gym.glove.device import min_jerk
from ias_gym.perturbed_starts import perturbed_starts

DT = 0.01
T = np.arange(0.0, 4.5, DT)
#: A fast see-saw (1.5 Hz, 0.3 rad) on one joint from 1.7 s, set in over a second.
VOLUNTARY = np.zeros((len(T), 10))
VOLUNTARY[:, 9] = (
    0.3
    * np.sin(2 * np.pi * 1.5 * np.clip(T - 1.7, 0, None))
    * np.array([min_jerk((t - 1.7) / 1.0) for t in T])
)


def _tremor(hz: float, amplitude: float) -> np.ndarray:
    phases = np.linspace(0.0, 2.0, 4)
    out = np.zeros((len(T), 10))
    out[:, :4] = amplitude * np.sin(2 * np.pi * hz * T[:, None] + phases)
    return out


def _run(canceller: TremorCanceller, x: np.ndarray) -> np.ndarray:
    canceller.reset()
    return np.array([xi + canceller.update(xi) for xi in x])


@pytest.mark.parametrize("hz", [4.0, 5.5, 8.0, 10.0, 12.0])
def test_a_tremor_anywhere_in_the_band_is_found_and_notched_out(hz: float) -> None:
    c = TremorCanceller(DT, window_s=0.3)
    tremor = _tremor(hz, 0.05)
    out = _run(c, VOLUNTARY + tremor)
    assert c.frequency_hz is not None and abs(c.frequency_hz - hz) < 0.3
    late = T > 3.0
    # what is left of the tremor on the shaking joints
    left = out[late, :4] - VOLUNTARY[late, :4]
    assert np.sqrt(np.mean(left**2)) < 0.2 * np.sqrt(np.mean(tremor[late, :4] ** 2))
    # the see-saw's joint, not shaking, is only delayed a little
    moved = out[late, 9] - VOLUNTARY[late, 9]
    assert np.sqrt(np.mean(moved**2)) < np.radians(-notch_phase_deg(1.5, c.frequency_hz)) * 0.3


def _closing_with_tremor(hz: float, n: int) -> np.ndarray:
    """``n`` steps of a fast close (0.3 rad in 0.5 s, minimum jerk) of one joint, with a
    tremor of ``hz`` and 0.05 rad on four: the first window of a session."""
    t = np.arange(n) * DT
    x = np.zeros((n, 10))
    x[:, 3] = 0.3 * np.array([min_jerk(ti / 0.5) for ti in t])
    if hz > 0:
        x[:, :4] += 0.05 * np.sin(2 * np.pi * hz * t[:, None] + np.linspace(0.0, 2.0, 4))
    return x


@pytest.mark.parametrize("hz", [4.0, 5.0])
@pytest.mark.parametrize("steps", [20, 30])
def test_a_slow_tremor_is_found_in_the_first_window(hz: float, steps: int) -> None:
    """Under a cycle or two of a 4-5 Hz tremor during a fast close: the fitted sinusoid is
    within 0.35 Hz of it, where the spectral peak of the high-passed targets (the estimate
    it replaced) is 0.4 Hz off or more, and three times as far."""
    x = _closing_with_tremor(hz, steps)
    line = sinusoid_line(x, DT)
    assert line is not None
    assert abs(line[0] - hz) < 0.35
    assert line[1] == pytest.approx(0.1, rel=0.15)  # the norm of four 0.05 rad sinusoids
    hp = butter(HIGHPASS_ORDER, HIGHPASS_HZ, btype="highpass", fs=1.0 / DT, output="sos")
    high_passed, _ = sosfilt(hp, x, axis=0, zi=sosfilt_zi(hp)[:, :, None] * x[0][None, None])
    spectral = abs(tremor_line(high_passed, DT)[0] - hz)
    assert spectral > max(0.4, 3.0 * abs(line[0] - hz))


def test_a_window_without_a_line_is_left_to_the_spectrum() -> None:
    """A close without a tremor is best fitted at the search's lowest frequency: no line
    (the canceller then takes the high-passed spectrum's peak)."""
    assert sinusoid_line(_closing_with_tremor(0.0, 30), DT) is None


def test_without_a_tremor_the_notch_only_delays() -> None:
    c = TremorCanceller(DT, window_s=0.3)
    out = _run(c, VOLUNTARY)
    # nothing before the first window
    np.testing.assert_array_equal(out[:29], VOLUNTARY[:29])
    # afterwards the voluntary motion is delayed by about the notch's phase lag at most
    # (and the retuning's small transients)
    worst = np.radians(-notch_phase_deg(1.5, TREMOR_BAND[0])) * 0.3
    assert np.abs(out - VOLUNTARY).max() < 1.15 * worst
    # a still pose is left where it is (the filters start at rest on it)
    c.reset()
    for _ in range(100):
        assert np.abs(c.update(np.full(10, 0.7))).max() < 1e-12


def test_the_notch_costs_a_voluntary_motion_little() -> None:
    assert notch_phase_deg(1.5, TREMOR_BAND[0]) > -15.0
    assert notch_phase_deg(1.5, TREMOR_BAND[1]) > -3.0
    with pytest.raises(ValueError, match="cannot see"):
        TremorCanceller(0.05, window_s=0.3)
    with pytest.raises(ValueError, match="4 control steps"):
        TremorCanceller(DT, window_s=0.02)


def test_the_assistant_takes_a_tremor_out_of_the_commands() -> None:
    """In the loop, from nearby starts: the hand's commanded targets keep a fraction of the
    tremor band the operator's have; without the canceller (the ablation) all of it."""
    env = gym.make(
        "IAS-GloveAssist-v0",
        person_id="p1",
        skill="tilt_left",
        impairment="tremor:hz=5,amplitude_rad=0.06",
    )
    u = env.unwrapped
    layout, scale = dict(u.observation_layout), u.config.action_scale  # type: ignore[attr-defined]
    band = butter(4, TREMOR_BAND, "bandpass", fs=1.0 / DT, output="sos")
    for tremor in (True, False):
        assistant = make_assistant(recogniser="none", layout=layout, tremor=tremor, pads=False)
        for options in list(perturbed_starts(env, 0)):
            obs, _ = env.reset(seed=0, options=options)
            assistant.reset()
            op, cmd, done = [], [], False
            while not done:
                action = assistant.act(obs)
                op.append(obs[layout["upcoming_theta"]].copy())
                cmd.append(op[-1] + scale * action)
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
            late = slice(100, None)  # from 1 s on
            p_op, p_cmd = (
                float(np.mean(sosfiltfilt(band, np.array(x), axis=0)[late] ** 2)) for x in (op, cmd)
            )
            if tremor:
                assert p_cmd < 0.05 * p_op
            else:
                assert p_cmd == pytest.approx(p_op)
    env.close()


@pytest.mark.parametrize("skill", ["lift_hold", "seesaw_fast"])
def test_an_operator_without_a_tremor_is_barely_touched(skill: str) -> None:
    """Without the detection (the ablation: the notch acts on every operator), an operator
    without a tremor gets offsets of a fraction of a 0.06 rad tremor's (RMS, from nearby
    starts): what the notch costs where a detection is wrong. The pad keeping, which may
    close a finger a step's worth where the pads meet later than the library's ever did,
    is off: tests/test_assist_pads.py tests it."""
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", skill=skill)
    u = env.unwrapped
    layout, scale = dict(u.observation_layout), u.config.action_scale  # type: ignore[attr-defined]
    assistant = make_assistant(recogniser="none", layout=layout, pads=False, detection=False)
    for options in list(perturbed_starts(env, 0)):
        obs, _ = env.reset(seed=0, options=options)
        assistant.reset()
        offsets, done = [], False
        while not done:
            action = assistant.act(obs)
            offsets.append(scale * action)
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
        assert np.sqrt(np.mean(np.square(offsets))) < 0.01
    env.close()


@pytest.mark.parametrize("degree", [1, 3, 5])
def test_a_curve_of_the_trends_degree_leaves_the_line_exact(degree: int) -> None:
    # a 1 s window: a polynomial of the trend's degree on every joint plus one line; the
    # polynomial lies in the fit's span, so the line is found at its own frequency and size
    t = np.arange(100) * DT
    u = np.linspace(-1.0, 1.0, len(t))
    curve = np.polynomial.polynomial.polyvander(u, degree) @ np.linspace(0.3, -0.2, degree + 1)
    line = 0.01 * np.sin(2 * np.pi * 9.3 * t + 0.4)
    window = np.repeat((curve + line)[:, None], 3, axis=1)
    found = sinusoid_line(window, DT, degree)
    assert found is not None
    assert found[0] == pytest.approx(9.3, abs=0.02)
    assert found[1] == pytest.approx(0.01 * np.sqrt(3), rel=0.02)


def test_a_window_under_a_slow_tremors_period_takes_a_straight_line() -> None:
    short = round(0.9 / TREMOR_BAND[0] / DT)  # under one period of the slowest tremor
    assert trend_basis(short, DT, 5).shape == (short, 2)
    assert trend_basis(100, DT, 5).shape == (100, 6)


def test_a_line_above_the_floor_is_notched_from_the_first_window() -> None:
    """Detection: a weak 12 Hz tremor (0.015 rad on 4 joints: a line of 0.03 rad) on the
    see-saw is notched out as without detection, from the first window on."""
    x = VOLUNTARY + _tremor(12.0, 0.015)
    gated, always = TremorCanceller(DT, 0.2, floor_rad=0.01), TremorCanceller(DT, 0.2)
    np.testing.assert_array_equal(_run(gated, x), _run(always, x))
    assert gated.engaged


def test_a_weak_line_is_left_alone_and_a_fading_tremor_released() -> None:
    """An operator's own line is weak: below the floor (0.004 rad on 4 joints is a line of
    0.008 rad) the targets pass untouched. A tremor that stops half way is notched while it
    lasts, and the targets pass untouched again a second after it stopped (the line's
    window is a second long). The quintic beside the line, as the shipped assistant's: a
    straight line leaves the see-saw's onset to a 4 Hz line of about 0.01 rad."""
    weak = VOLUNTARY + _tremor(8.0, 0.004)
    c = TremorCanceller(DT, 0.2, trend_degree=5, floor_rad=0.01)
    np.testing.assert_array_equal(_run(c, weak), weak)
    stop = len(T) // 2
    fading = VOLUNTARY + _tremor(8.0, 0.02) * (np.arange(len(T)) < stop)[:, None]
    out = _run(c, fading)
    assert np.abs(out[stop - 50 : stop] - fading[stop - 50 : stop]).max() > 0.005
    after = stop + round(1.2 / DT)
    np.testing.assert_array_equal(out[after:], fading[after:])
    with pytest.raises(ValueError, match="floor"):
        TremorCanceller(DT, 0.2, floor_rad=-0.01)
