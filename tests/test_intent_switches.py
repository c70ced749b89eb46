"""Intent switches: the phase recogniser's switching model (its recursion against brute force,
an operator who changes their mind followed to the skill they switched to) and how switches
are counted."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ias_gym.assist.intent_switches import SwitchSession, evaluate_switches
from ias_gym.assist.phase_recogniser import (
    PHASE_SWITCH_RATE,
    PHASE_TEMPER,
    PhaseRecogniser,
    rate_of_cost,
    switch_cost,
    switching_step,
)
from ias_gym.assist.recognition import UNKNOWN, LibrarySession
from ias_gym.assist.recognition_features import FEATURE_SCALE, FEATURE_T0
from ias_gym.assist.sessions import intent_latency
from ias_gym.assist.stream import SessionFrame
from ias_gym.errors import InputError
from ias_gym.glove.hand import N_JOINTS, joint_index


def _random_terms(rng: np.random.Generator, t: int, k: int, h: int) -> tuple[np.ndarray, ...]:
    z2 = rng.uniform(0.0, 20.0, size=(t, k, h))
    ll = -0.5 * PHASE_TEMPER * (z2 + rng.uniform(0.0, 2.0, size=(1, k, h)))
    return ll, z2


def test_without_switches_the_recursion_is_the_plain_sum() -> None:
    rng = np.random.default_rng(0)
    ll, z2 = _random_terms(rng, 5, 3, 4)
    alpha, path = ll[0], z2[0]
    for t in range(1, 5):
        alpha, path = switching_step(alpha, path, ll[t], z2[t], 0.0)
    np.testing.assert_allclose(alpha, ll.sum(axis=0))
    np.testing.assert_allclose(path, z2.sum(axis=0))


@pytest.mark.parametrize("rate", [1e-3, 0.2])
def test_the_forward_recursion_is_the_hmm_of_a_fixed_share_prior(rate: float) -> None:
    """Brute force: every skill sequence of a short session, its prior a product of stay
    (1 - rate) and switch (rate / (K - 1)) factors, the hypothesis kept; the best path's
    cost its frames' squared z and a switch cost per switch."""
    rng = np.random.default_rng(1)
    t_len, k, h = 4, 3, 2
    ll, z2 = _random_terms(rng, t_len, k, h)
    alpha, path = ll[0], z2[0]
    for t in range(1, t_len):
        alpha, path = switching_step(alpha, path, ll[t], z2[t], rate)
    cost = switch_cost(rate, k)
    for j in range(h):
        for last in range(k):
            total, best = 0.0, math.inf
            for seq in itertools.product(range(k), repeat=t_len):
                if seq[-1] != last:
                    continue
                switches = sum(a != b for a, b in itertools.pairwise(seq))
                prior = (1 - rate) ** (t_len - 1 - switches) * (rate / (k - 1)) ** switches
                total += prior * math.exp(sum(ll[t, s, j] for t, s in enumerate(seq)))
                best = min(best, switches * cost + sum(z2[t, s, j] for t, s in enumerate(seq)))
            assert alpha[last, j] == pytest.approx(math.log(total), rel=1e-9)
            assert path[last, j] == pytest.approx(best, rel=1e-9)


def test_the_switch_cost_is_the_tempered_log_odds() -> None:
    assert switch_cost(0.0, 6) == math.inf
    assert switch_cost(0.1, 1) == math.inf
    assert switch_cost(0.1, 2) == pytest.approx(2 / PHASE_TEMPER * math.log(9.0))
    assert switch_cost(1e-9, 6) > switch_cost(1e-3, 6)
    assert switch_cost(0.1, 2, temper=0.05) == pytest.approx(2 / 0.05 * math.log(9.0))


@pytest.mark.parametrize(("rate", "skills", "temper"), [(1e-20, 6, 0.1), (3e-7, 5, 0.035)])
def test_the_rate_of_a_cost_inverts_the_cost(rate: float, skills: int, temper: float) -> None:
    cost = switch_cost(rate, skills, temper)
    assert rate_of_cost(cost, skills, temper) == pytest.approx(rate, rel=1e-9)


# --- a library of three made-up skills of the wrist's flexion and deviation
DT = 0.01
END = 4.0
SKILL_AXES = {"flex": (0, 1.0), "extend": (0, -1.0), "deviate": (1, 1.0)}


def _motion(skill: str, t: np.ndarray, amplitude: float) -> np.ndarray:
    """``(T, 8)`` features: the skill's axis ramps by ``amplitude`` (feature units) over 1.5 s
    from FEATURE_T0, smoothly."""
    axis, sign = SKILL_AXES[skill]
    s = np.clip((t - FEATURE_T0) / 1.5, 0.0, 1.0)
    out = np.zeros((len(t), 8))
    out[:, axis] = sign * amplitude * (10 * s**3 - 15 * s**4 + 6 * s**5)
    return out


def _library(rng: np.random.Generator) -> list[LibrarySession]:
    t = np.arange(0.0, END, DT)
    out = []
    for person in range(4):
        for skill in SKILL_AXES:
            f = _motion(skill, t, 8.0 * (1 + 0.1 * rng.standard_normal()))
            f += 0.1 * rng.standard_normal(f.shape) * (t >= FEATURE_T0)[:, None]
            out.append(LibrarySession(skill, f"p{person}", f, t))
    return out


def _frames(features: np.ndarray, t: np.ndarray) -> list[SessionFrame]:
    """Frames whose recogniser features are ``features`` (the wrist's flexion and deviation)."""
    frames = []
    for x, time_s in zip(features, t, strict=True):
        theta = np.zeros(N_JOINTS)
        theta[joint_index("wrist_flexion")] = x[0] * FEATURE_SCALE[0]
        theta[joint_index("wrist_deviation")] = x[1] * FEATURE_SCALE[1]
        frames.append(
            SessionFrame(
                time_s=float(time_s),
                readings=np.full(N_JOINTS, np.nan),
                theta=theta,
                tau_display=np.zeros(5),
                pen_position=np.zeros(3),
                pen_rpy=np.zeros(3),
            )
        )
    return frames


def _run(rec: PhaseRecogniser, frames: list[SessionFrame]) -> list[str]:
    rec.reset()
    return [rec.update(f).best for f in frames]


def test_a_switched_skill_is_followed_and_a_plain_one_kept() -> None:
    """Flex until 2.3 s, then extend (each at its phase, blended over 0.2 s): the fitted
    switching model names ``extend`` after the switch and to the end; the one-skill model
    does not. A plain session stays its skill under both, and a skill the library lacks ends
    unknown."""
    rng = np.random.default_rng(2)
    library = _library(rng)
    t = np.arange(0.0, END, DT)
    w = np.clip((t - 2.3) / 0.2, 0.0, 1.0)[:, None]
    switched = (1 - w) * _motion("flex", t, 8.0) + w * _motion("extend", t, 8.0)
    switching, single = PhaseRecogniser(library), PhaseRecogniser(library, 0.0)
    top = _run(switching, _frames(switched, t))
    # followed before the session ends (the real sessions' latencies are the table's)
    assert math.isfinite(intent_latency(t, top, "extend", 2.3))
    assert _run(single, _frames(switched, t))[-1] != "extend"
    plain = _frames(_motion("flex", t, 8.0), t)
    assert _run(switching, plain)[-1] == _run(single, plain)[-1] == "flex"
    known = [s for s in library if s.skill != "deviate"]
    deviate = _frames(_motion("deviate", t, 8.0), t)
    assert _run(PhaseRecogniser(known), deviate)[-1] == UNKNOWN


def test_the_switch_rate_and_temper_are_the_fitted_ones() -> None:
    """``PHASE_SWITCH_RATE`` and ``PHASE_TEMPER`` are what ``train/fit_switch_rate.py`` chose
    (its report)."""
    report = json.loads((Path(__file__).parents[1] / "docs" / "switch_rate_fit.json").read_text())
    assert report["set"] == "development"
    assert PHASE_SWITCH_RATE == report["switch_rate"] > 0
    assert PHASE_TEMPER == report["temper"] > 0


def test_stepping_and_scoring_a_whole_session_agree() -> None:
    """``score_session`` (the leave-one-out calibration's path) gives what stepping frame by
    frame gives, switches included."""
    library = _library(np.random.default_rng(4))
    t = np.arange(0.0, END, DT)
    w = np.clip((t - 2.5) / 0.2, 0.0, 1.0)[:, None]
    frames = _frames((1 - w) * _motion("deviate", t, 8.0) + w * _motion("flex", t, 8.0), t)
    rec = PhaseRecogniser(library)
    rec.reset()
    for f in frames:
        stepped = rec.update(f)
    novelty = rec.novelty
    scored, scored_novelty = rec.score_session(frames)
    assert scored_novelty == pytest.approx(novelty, rel=1e-9)
    for name in stepped:
        assert scored[name] == pytest.approx(stepped[name], abs=1e-9)


def test_a_switch_rate_or_temper_outside_its_range_is_refused() -> None:
    library = _library(np.random.default_rng(3))
    for rate in (-0.1, 1.0, math.nan):
        with pytest.raises(InputError, match="switch_rate"):
            PhaseRecogniser(library, rate)
    for temper in (0.0, -0.1, 1.5, math.nan):
        with pytest.raises(InputError, match="temper"):
            PhaseRecogniser(library, temper=temper)


class _Scripted:
    """A recogniser that names ``first`` before ``at`` [s] and ``second`` from then on."""

    skills = ("a", "b")

    def __init__(self, first: str, second: str, at: float) -> None:
        self.first, self.second, self.at = first, second, at

    def reset(self) -> None:
        pass

    def update(self, frame: SessionFrame) -> dict[str, float]:
        best = self.first if frame.time_s < self.at else self.second
        return {name: float(name == best) for name in (*self.skills, UNKNOWN)}


def test_switches_are_counted_followed_with_their_latency() -> None:
    t = np.arange(0.0, 3.0, DT)
    frames = _frames(np.zeros((len(t), 8)), t)
    session = SwitchSession("p", "a", "b", 2.0, frames)
    followed = evaluate_switches(_Scripted("a", "b", 2.25), [session, session])  # type: ignore[arg-type]
    assert followed["switches_followed"] == 1.0
    assert followed["switch_latency_s"] == pytest.approx(0.25)
    assert followed["rates"]["switches_followed"]["trials"] == 2
    lost = evaluate_switches(_Scripted("a", UNKNOWN, 2.25), [session])  # type: ignore[arg-type]
    assert lost["switches_followed"] == 0.0
    assert lost["switch_latency_s"] is None and lost["switch_latencies_s"] == [None]
    with pytest.raises(InputError, match="no switch sessions"):
        evaluate_switches(_Scripted("a", "b", 0.0), [])  # type: ignore[arg-type]


def test_intent_latency_edges() -> None:
    times = np.array([1.0, 2.0, 3.0, 4.0])
    assert intent_latency(times, ["b", "b", "b", "b"], "b", 2.0) == 0.0
    assert intent_latency(times, ["a", "a", "b", "b"], "b", 2.0) == pytest.approx(1.0)
    assert intent_latency(times, ["a", "b", "b", "a"], "b", 2.0) == math.inf
    assert math.isnan(intent_latency(times, [], "b", 2.0))
