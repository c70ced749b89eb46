"""IAS-GloveAssist-v0 (ias_gym.assist): spaces, determinism, the impairments as specified,
the analytic assistant rescuing a weak grip from perturbed starts without harming an
unimpaired operator, the intervention metric, the CLI's JSON and the assistant on the CAN
glove's env."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.assist.assistance_evaluation import REFERENCE_STARTS, reference_session
from ias_gym.assist.assistants import (
    BIAS_THRESHOLD,
    CLOSING_DEADBAND,
    COORDINATE_UNTIL,
    OPENING_WINDOW,
    PUSH_DISTANCE,
    REST_WINDOW,
    AnalyticAssistant,
    _along,
)
from ias_gym.assist.pinch_geometry import closing_direction
from ias_gym.assist.sessions import (
    HELD_FROM,
    POSITION_TOLERANCE,
    SessionResult,
    run_session,
    session_success,
)
from ias_gym.assist.skill_templates import load_templates
from ias_gym.errors import InputError
from ias_gym.glove.hand import PersonParams, joint_index
from ias_gym.glove.impairment_spec import FAMILIES
from ias_gym.glove.impairments import (
    DEFAULT_STRENGTHS,
    TREMOR_BAND,
    Impairment,
    calibration_bias,
    pinch_direction,
    reference_kwargs,
)
from ias_gym.glove.population import PARAMETERS, population_ids
from ias_gym.glove.profile_cache import default_calibration
from ias_gym.glove.skills import skill_start_time
from tests.closed_loop import perturbed_starts

#: A development person (never one of the tables' held-out persons).
PERSON = "p3"


def typical_persons(k: int, seed: int = 0) -> tuple[str, ...]:
    """The first ``k`` persons of the population drawn with ``seed`` whose range of motion
    lies within half a standard deviation of the population's mean.

    The range of motion is the parameter an unimpaired pinch's difference from the
    library's follows: a person whose range is narrower closes the pinch less far (their
    plan is clipped to their range), and the weak grip's opening estimate takes that for
    a weak grip (measured, lift_hold, seed 0, 40 persons of population seed 0: all 11
    with a range of motion below 0.92 were given an opening, 0.004-0.095 rad; of the 29
    with 0.93-1.24 one, 0.011 rad).
    """
    dist = PARAMETERS["range_of_motion"].distribution
    ids = tuple(
        p
        for p in population_ids(20 * k, seed)
        if abs(PersonParams.sample(p).range_of_motion - dist.a) <= 0.5 * dist.b
    )
    assert len(ids) >= k, f"fewer than {k} persons of population seed {seed} within half an SD"
    return ids[:k]


def typical_person(seed: int = 0) -> str:
    """The first of :func:`typical_persons`."""
    return typical_persons(1, seed)[0]


@pytest.fixture(scope="module")
def templates() -> dict:
    return load_templates()


def make(**kw):
    return gym.make("IAS-GloveAssist-v0", person_id=PERSON, **kw)


def test_spaces_and_the_upcoming_targets_are_the_next_steps() -> None:
    env = make(skill="tilt_left")
    obs, info = env.reset(seed=0)
    assert env.action_space.shape == (10,)
    assert obs.shape == env.observation_space.shape == (49,)
    for _ in range(3):
        upcoming = obs[env.unwrapped.observation_layout["upcoming_theta"]].copy()
        obs, *_, info = env.step(np.zeros(10))
        # the assistant sees the targets the hand gets in the next step, not the last ones
        np.testing.assert_array_equal(info["operator_theta"], upcoming)
    assert info["intent"] == "tilt_left" and info["impairment"] == "none"
    with pytest.raises(InputError, match="impairment"):
        make(impairment="palsy")
    with pytest.raises(InputError, match="switch_time"):
        make(switch_to="tilt_right")
    with pytest.raises(InputError, match=r"hand_size: scale=3.0 is out of range \(0.8..1.25\)"):
        make(impairment="hand_size", strength=3.0)


def test_same_seed_same_session() -> None:
    a, b = make(impairment="tremor"), make(impairment="tremor")
    oa, _ = a.reset(seed=3)
    ob, _ = b.reset(seed=3)
    for _ in range(20):
        oa, *_ = a.step(np.full(10, 0.1))
        ob, *_ = b.step(np.full(10, 0.1))
    np.testing.assert_array_equal(oa, ob)


def _operator_thetas(impairment: str, steps: int, seed: int = 0) -> np.ndarray:
    """The operator's calibrated targets over ``steps`` steps (no physics needed: the
    glove is read ahead, so the targets come from the glove chain alone)."""
    env = make(impairment=impairment).unwrapped
    env.reset(seed=seed)
    out = [env.upcoming_theta.copy()]
    for _ in range(steps):
        env.step(np.zeros(10))
        out.append(env.upcoming_theta.copy())
    return np.array(out)


def test_tremor_peaks_in_8_to_12_hz_and_matters() -> None:
    n = 128
    diff = _operator_thetas("tremor", n) - _operator_thetas("none", n)
    pron = diff[:, joint_index("wrist_pronation")]
    spectrum = np.abs(np.fft.rfft(pron - pron.mean()))
    freqs = np.fft.rfftfreq(len(pron), d=0.01)
    peak = freqs[np.argmax(spectrum)]
    assert TREMOR_BAND[0] <= peak <= TREMOR_BAND[1]
    # after the env's low-pass still several times the persons' own tremor (<= 3 mrad)
    assert np.ptp(pron[20:]) > 0.03


def test_lag_delays_the_readings_by_100_ms() -> None:
    lagged, plain = make(impairment="lag").unwrapped, make().unwrapped
    ga, gb = lagged._impaired_glove(7), plain._impaired_glove(7)
    a = np.array([ga.read().psi for _ in range(40)])
    b = np.array([gb.read().psi for _ in range(40)])
    k = round(DEFAULT_STRENGTHS["lag"] / 0.01)
    assert k == 10
    np.testing.assert_array_equal(a[k:], b[:-k])
    np.testing.assert_array_equal(a[:k], np.repeat(b[:1], k, axis=0))


def test_biased_calibration_offsets_the_pinching_joints() -> None:
    env = make(impairment="biased_calibration").unwrapped
    psi = np.random.default_rng(0).normal(0.0, 0.3, size=(20, 10))
    shift = env.calibration.predict(psi) - default_calibration(env.person).predict(psi)
    bias = calibration_bias(DEFAULT_STRENGTHS["biased_calibration"])
    np.testing.assert_allclose(shift, np.broadcast_to(bias, shift.shape), atol=1e-12)
    assert bias[joint_index("index_mcp")] < 0 and bias[joint_index("wrist_flexion")] == 0


@pytest.mark.closed_loop
def test_weak_grip_opens_the_pinch_after_the_close() -> None:
    diff = _operator_thetas("weak_grip", 90) - _operator_thetas("none", 90)
    # after the close phase (0.7 s) the targets are opened along the pinch direction (seen
    # through the person's calibration, which couples the index PIP and DIP a little)
    late = diff[80:].mean(axis=0)
    expected = -DEFAULT_STRENGTHS["weak_grip"] * pinch_direction()
    main = [joint_index("index_mcp"), joint_index("thumb_flexion")]
    np.testing.assert_allclose(late[main], expected[main], atol=0.005)
    assert np.abs(late[:3]).max() < 1e-3  # the wrist is untouched
    assert np.abs(diff[0]).max() < 0.01  # the pre-shape is the person's own


def test_hand_size_is_another_hand_running_the_stock_pinch() -> None:
    env = make(impairment="hand_size").unwrapped
    assert env.person.hand_scale == pytest.approx(DEFAULT_STRENGTHS["hand_size"])
    assert env.operator_person.hand_scale == 1.0
    assert env.person.person_id == PERSON
    # its reference: the same hand, with an operator planning for it (the plan the only change)
    same = make(**reference_kwargs(env.impairment)).unwrapped
    assert same.person == env.person and same.operator_person == env.person
    np.testing.assert_array_equal(same.model.body_pos, env.model.body_pos)
    assert not np.allclose(same.script(1.0), env.script(1.0))
    assert reference_kwargs(Impairment.make("weak_grip")) == {}
    for bad in ({"hand_scale": 0.0}, {"hand_scale": 1.2, "impairment": "hand_size"}):
        with pytest.raises(InputError, match="hand_scale"):
            make(**bad)


@pytest.mark.closed_loop
def test_assistant_turns_a_weak_grip_into_a_success(templates) -> None:
    """Three persons of a typical range of motion: each one's weak grip drops the pen without
    help, and for at least two of them the assistant saves the session from every nearby
    start (measured: all four of the first such persons with the default calibrations, three
    of four with calibrations trained under seed 1)."""
    kw = {"skill": "lift_hold", "duration": 2.5}
    saved = 0
    for person in typical_persons(3):
        reference = run_session(gym.make("IAS-GloveAssist-v0", person_id=person, **kw), None, 0)
        env = gym.make("IAS-GloveAssist-v0", person_id=person, impairment="weak_grip", **kw)
        unassisted = run_session(env, None, 0)
        assert not session_success(unassisted, reference), person  # the pen falls without help
        saved += all(
            session_success(run_session(env, AnalyticAssistant(templates), 0, options), reference)
            for options in perturbed_starts(env, 0, n=2)
        )
        env.close()
    assert saved >= 2


@pytest.mark.closed_loop
def test_no_loss_for_the_unimpaired_operator(templates) -> None:
    """A typical unimpaired person (:func:`typical_person`) is left to do the skill: the
    assisted session is their own from nearby starts (:func:`session_success`), and the
    tremor and coordination terms stay off. How much the assistant still acts depends on
    the trained calibration's bits (intervention 0.013 with the default calibration, 0.03-
    0.057 with ones trained under seed 2, measured), so it is not asserted here."""
    env = gym.make(
        "IAS-GloveAssist-v0", person_id=typical_person(), skill="tilt_right", duration=2.5
    )
    reference = run_session(env, None, 0)
    assert reference.held_throughout()
    for options in perturbed_starts(env, 0, n=2):
        assistant = AnalyticAssistant(templates)
        assisted = run_session(env, assistant, 0, options)
        assert session_success(assisted, reference), options is None
        # no tremor and no pad pushing the pen alone: those terms stay off. The opening
        # is an estimate near its deadband for a person whose own pinch differs from the
        # library's (a calibration trained under another seed or with other last bits put
        # it 6.5-17 mrad past): it stays below the smallest weak grip the impairment draws
        assert not assistant.tremor_detected
        assert assistant.opening < FAMILIES["weak_grip"]["rad"].sample[0]
        assert assistant.coordinated_at is None


def _constructed_close(
    templates, env, touch_at: float, push: float, *, both: bool = False, tremor: bool = False
) -> tuple[AnalyticAssistant, np.ndarray, np.ndarray]:
    """A close constructed step by step: the operator closes both fingers along the pinch's
    direction at 0.5 rad/s; from ``touch_at`` [s] the index pad touches the pen (the thumb
    too if ``both``) and pushes it ``push`` [m/s]. Returns the assistant, the last targets
    and its last offsets."""
    assistant = AnalyticAssistant(templates)
    assistant.reset(env)
    assistant.tremor_detected = tremor
    pen = env.data.xpos[env._pen_body].copy()
    theta0 = env.upcoming_theta.copy()
    dt = env.config.control_dt
    theta, out = theta0, np.zeros(10)
    for k in range(1, round(COORDINATE_UNTIL / dt) + 11):
        t = k * dt
        touching = t >= touch_at
        env._touch = (touching, touching and both)
        env._pen_start = pen - np.array([push * max(t - touch_at, 0.0), 0.0, 0.0])
        theta = theta0 + 0.5 * t * pinch_direction()
        out = assistant._coordinate_offset(env, t, theta)
    return assistant, theta, out


def test_a_pad_pushing_the_pen_alone_waits_for_the_other(templates) -> None:
    """A pad that comes to the pen first and pushes it on its own (a larger hand than the
    operator plans for brings the index first) is held back to the pose of its first touch
    while the other finger reaches for the pen; a pad the pen rests on from the start, a
    push shorter than PUSH_DISTANCE, a pad shaken by a tremor and a pinch whose pads touch
    together are left alone. The situation is constructed: on the population's hands the
    stock plan seldom makes it (lift_hold, seed 0, a hand of scale 1.2: the pad was held
    back in none of 9 sessions with a reference, 8 of which held the pen without help)."""
    env = make(duration=1.2).unwrapped
    env.reset(seed=0)
    dt = env.config.control_dt
    index = [joint_index("index_mcp"), joint_index("index_pip")]
    thumb = [joint_index("thumb_cmc"), joint_index("thumb_flexion")]
    touch_at, speed = 0.3, 0.05  # the pen pushed 2 mm in 40 ms
    assistant, theta, out = _constructed_close(templates, env, touch_at, speed)
    assert assistant.coordinated_at is not None
    assert touch_at < assistant.coordinated_at <= touch_at + PUSH_DISTANCE / speed + 2 * dt
    first = np.asarray(env.upcoming_theta) + 0.5 * touch_at * pinch_direction()
    np.testing.assert_allclose((theta + out)[index], first[index], atol=1e-12)
    reach = out[thumb] / closing_direction(env)[thumb]  # the thumb moves toward the index
    assert np.all(reach > 0)
    for kw in (
        {"touch_at": dt, "push": speed},  # the pen rests on the pad from the start
        {"touch_at": touch_at, "push": 0.5 * PUSH_DISTANCE / COORDINATE_UNTIL},  # too short
        {"touch_at": touch_at, "push": speed, "tremor": True},  # a tremor's shaking
        {"touch_at": touch_at, "push": speed, "both": True},  # both pads came together
    ):
        assistant, _, out = _constructed_close(templates, env, **kw)
        assert assistant.coordinated_at is None, kw
        np.testing.assert_array_equal(out, np.zeros(10))


@pytest.mark.closed_loop
def test_the_pad_the_pen_rests_on_is_not_held_back(templates) -> None:
    """The pen lies on the thumb pad from the start; p6's unimpaired close (a development
    person, seed 1) slides it 2.3 mm on the thumb before the index arrives. That is the
    person's own close: holding the thumb back there (a rule for any first lone pad) left
    the pinch too weak and dropped the pen at 3.0 s (measured)."""
    reference = reference_session("p6", "seesaw_slow", 1)
    assert reference is not None
    env = gym.make("IAS-GloveAssist-v0", person_id="p6", skill="seesaw_slow")
    for options in perturbed_starts(env, 1, n=2):
        assistant = AnalyticAssistant(templates)
        assert session_success(run_session(env, assistant, 1, options), reference)
        assert assistant.coordinated_at is None, options is None


@pytest.mark.closed_loop
def test_a_lagged_operator_is_left_alone(templates) -> None:
    """A 100 ms lag delays an open-loop operator's session: the skill done 0.1 s late. The
    assistant must not pull the late place toward the template's clock (with the height term
    against the template's time only, a lagged lift_place was 3.2 mm off its own session,
    measured): a typical person's (:func:`typical_person`) lagged session, assisted, is
    still their own session by the evaluation's test (:func:`session_success`, 3 mm).
    Measured: within 0.03 mm and intervention 0.0004 with the default calibration; 0.5-1.4
    mm and intervention 0.024-0.15 with ones trained under seeds 1 and 2: how much the
    assistant acts on a lagged person depends on the calibration's bits (an open question
    of the assistant), so it is not asserted here."""
    person = typical_person()
    reference = reference_session(person, "lift_place", 5)
    assert reference is not None
    env = gym.make("IAS-GloveAssist-v0", person_id=person, skill="lift_place", impairment="lag")
    assert session_success(run_session(env, None, 5), reference)  # late, but the skill
    for options in perturbed_starts(env, 5, n=2):
        assisted = run_session(env, AnalyticAssistant(templates), 5, options)
        assert session_success(assisted, reference), options is None


def _height_correction(templates, env, late: float) -> float:
    """The largest wrist correction of the height term [rad] on a pen that follows the
    template of the env's skill ``late`` [s] behind it (constructed: the pen's start is
    moved under the resting pen, step by step)."""
    skill = str(env.config.skill)
    template = templates[skill]
    assistant = AnalyticAssistant(templates)
    assistant.reset(env)
    pen = env.data.xpos[env._pen_body].copy()
    dt = env.config.control_dt
    largest = 0.0
    for k in range(1, round(env.config.duration / dt) + 1):
        t = k * dt
        tau = assistant._template_time(template, t)
        env._pen_start = pen - np.array([0.0, 0.0, template.height_at(tau - late)])
        assistant._height_offset(env, t, {skill: 1.0})
        largest = max(largest, abs(assistant.h))
    return largest


def test_a_late_pen_within_the_time_band_is_no_height_error(templates) -> None:
    """The height term compares the pen with the template's heights within
    HEIGHT_TIME_TOLERANCE of now: a place 0.1 s late (a lagged operator's) is on time, one
    0.3 s late is corrected."""
    env = gym.make("IAS-GloveAssist-v0", person_id=typical_person(), skill="lift_place")
    env.reset(seed=0)
    assert _height_correction(templates, env.unwrapped, 0.1) == 0.0
    assert _height_correction(templates, env.unwrapped, 0.3) > 0.01


def _lift(pen_dx: float = 0.0, off: tuple[float, float] = (math.inf, math.inf)) -> SessionResult:
    """A synthetic lift-and-hold session (no simulation): the pen lifted 4 cm over the
    lift, moved ``pen_dx`` [m] sideways after the skill's start, the pads off it from
    ``off[0]`` to ``off[1]`` [s]."""
    times = np.arange(1, 401) * 0.01
    start = skill_start_time("lift_hold", PERSON)
    z = 0.04 * np.clip((times - HELD_FROM) / (start - HELD_FROM), 0.0, 1.0)
    x = pen_dx * np.clip(times - start, 0.0, 1.0)
    pinched = (times < off[0]) | (times >= off[1])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(times), 1))
    return SessionResult(
        times, np.stack([x, 0 * x, z], axis=1), quat, True, bool(pinched[-1]), start, 0.0,
        pinched=pinched,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("nearby", "is_reference"),
    [
        ([_lift(), _lift()], True),  # every start agrees: the seed's own session judges
        ([_lift(), _lift(off=(3.0, math.inf))], False),  # a start 1e-9 away drops the pen
        ([_lift(pen_dx=3 * POSITION_TOLERANCE), _lift()], False),  # one moves it elsewhere
        ([_lift(off=(2.0, 2.3)), _lift()], False),  # one loses a pad and grasps again
    ],
    ids=["agree", "drops", "moves", "regrasps"],
)
def test_a_knife_edge_reference_is_no_reference(
    monkeypatch: pytest.MonkeyPatch, nearby: list[SessionResult], is_reference: bool
) -> None:
    """A person whose unimpaired session holds the pen from the seed's start but not from a
    start 1e-9 away loses it on another machine without any assistant, so it judges nothing:
    :func:`reference_session` runs the seed's start and each of ``REFERENCE_STARTS`` nearby
    ones (here sessions made up, so the test is of the rule, not of one person's chaos) and
    keeps the first only when each other one holds the pen from the lift on and agrees with
    it; a first that fails itself is none either."""
    import ias_gym.assist.assistance_evaluation as evaluation

    assert len(nearby) == REFERENCE_STARTS
    env = make(skill="lift_hold")
    expected_starts = list(perturbed_starts(env, 0, REFERENCE_STARTS))
    own = _lift()
    calls: list[dict | None] = []

    def fake_run_session(env, assistant, seed, options=None):
        assert assistant is None and seed == 0
        calls.append(options)
        return own if len(calls) == 1 else nearby[len(calls) - 2]

    monkeypatch.setattr(evaluation, "run_session", fake_run_session)
    reference = reference_session(PERSON, "lift_hold", 0)
    assert (reference is own) if is_reference else (reference is None)
    # the seed's own start first (the perturbation mode's moved one), then the nearby ones
    assert len(calls) == 1 + REFERENCE_STARTS or not is_reference
    for got, want in zip(calls, expected_starts, strict=False):
        if want is None:
            assert got is None
        else:
            assert got is not None
            np.testing.assert_array_equal(got["qpos"], want["qpos"])
    # a first session that does not hold the pen throughout is no reference at all
    own = _lift(off=(2.0, 2.3))
    calls.clear()
    assert reference_session(PERSON, "lift_hold", 0) is None
    assert len(calls) == 1


@pytest.mark.parametrize("impairment", ["none", "tremor"])
def test_the_tremor_filter_acts_only_on_a_tremor(templates, impairment: str) -> None:
    env = make(impairment=impairment, duration=0.5)
    assistant = AnalyticAssistant(templates, squeeze=False, height=False)
    result = run_session(env, assistant, 0)
    assert assistant.tremor_detected == (impairment == "tremor")
    assert (result.intervention > 0.0) == (impairment == "tremor")


@pytest.mark.closed_loop
def test_the_opening_of_a_biased_calibration_is_estimated(templates) -> None:
    """The bias opens both fingers by 0.10 rad along the pinch's direction, at rest too; the
    rest pose shows it, and the thumb's rest (a person's own: within 0.01 rad of the
    library's) bounds it. Over five persons of a typical range of motion the estimate never
    exceeds the bias by more than 15 %, the opening undone is never less than it, and it is
    found (above 0.4 of it) for most of them. How many it estimates within -30..+15 %
    depends on the trained calibrations' bits: 4-5 of 5 with the default ones and those
    trained under seeds 2 and 3, 2 of 5 under seed 1 (0.048, 0.098, 0.100, 0.055 and 0.0
    rad, measured); the assistant's figures over a population are the assisting table's."""
    bias = DEFAULT_STRENGTHS["biased_calibration"]
    estimates = []
    for person in typical_persons(5):
        env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=person,
            impairment="biased_calibration",
            skill="lift_hold",
            duration=1.2,
        )
        assistant = AnalyticAssistant(templates, height=False)
        run_session(env, assistant, 0)
        env.close()
        assert assistant.opening >= assistant.bias, person
        estimates.append(assistant.bias)
    assert all(b < 1.15 * bias for b in estimates), estimates
    assert sum(b > 0.4 * bias for b in estimates) >= 3, estimates


#: Persons of the closing test: seven of a typical range of motion (by the rule, not by an
#: outcome).
CLOSING_PERSONS = typical_persons(7)


@pytest.mark.closed_loop
def test_a_weak_grip_hidden_in_the_hold_is_seen_in_its_closing(
    templates, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A person whose own pinch is closer than the library's hides a weak grip in the
    hold's pose; its closing from rest still falls short. With the hold's pose blind (its
    deadband infinite, as for such a person), the closing alone opens the weak grip's pinch
    (> 0.01 rad) for most of seven persons of a typical range of motion, each person's at
    least as far as their unimpaired pinch and on average more than three times as far;
    blind as well, nothing opens it. The estimate reads the operator's targets, before the
    physics: no start 1e-9 away changes it, but another trained calibration does."""
    import ias_gym.assist.assistants as assistants

    def opening(person: str, impairment: str) -> float:
        env = gym.make(
            "IAS-GloveAssist-v0",
            person_id=person,
            impairment=impairment,
            skill="tilt_left",
            duration=OPENING_WINDOW[1] + 0.05,  # the estimate is final at the window's end
        )
        assistant = AnalyticAssistant(templates, height=False)
        run_session(env, assistant, 3)
        env.close()
        return assistant.opening

    monkeypatch.setattr(assistants, "OPENING_DEADBAND", math.inf)
    weak = {person: opening(person, "weak_grip") for person in CLOSING_PERSONS}
    assert sum(o > 0.01 for o in weak.values()) > len(weak) / 2, weak
    # Another trained calibration can give an unimpaired person an opening too (up to 0.041
    # rad with calibration seeds 1-3, against 0.008-0.117 for the weak grips): the weak grip
    # opens each person's pinch at least as far, and on average far more.
    none = {person: opening(person, "none") for person in CLOSING_PERSONS}
    assert all(weak[p] >= none[p] for p in CLOSING_PERSONS), (weak, none)
    assert np.mean(list(weak.values())) > 3.0 * np.mean(list(none.values())), (weak, none)
    monkeypatch.setattr(assistants, "CLOSING_DEADBAND", math.inf)
    assert opening("p3", "weak_grip") == 0.0


#: The person of population seed 0 whose unimpaired rest opens the index the most against
#: the library's (+0.16 rad; 40 persons measured, lift_hold, seed 0).
OPEN_REST = "pop0-008-8c5466"


@pytest.mark.closed_loop
@pytest.mark.parametrize(
    ("person", "impairment"),
    [("d4", "none"), (PERSON, "none"), (OPEN_REST, "none"), (PERSON, "hand_size")],
)
def test_an_unbiased_rest_pose_is_no_bias(templates, person: str, impairment: str) -> None:
    """A person's own rest pose differs from the library's in the index (40 persons of
    population seed 0: -0.015..+0.16 rad unimpaired, up to +0.11 rad with a hand 1.2 times
    the size the operator plans for) but not in the thumb (within 0.006 rad): the less
    opened finger stays far below the bias threshold, and no bias is seen."""
    env = gym.make(
        "IAS-GloveAssist-v0",
        person_id=person,
        impairment=impairment,
        skill="lift_hold",
        duration=1.2,
    )
    for options in perturbed_starts(env, 0, n=2):
        assistant = AnalyticAssistant(templates, height=False)
        run_session(env, assistant, 0, options)
        assert assistant.bias == 0.0
        rest = np.mean(assistant._rest, axis=0)
        assert min(_along(rest, f) for f in assistant._pinch_fingers) < 0.5 * BIAS_THRESHOLD


def _estimate(templates, env, rest: np.ndarray, hold: np.ndarray) -> tuple[float, float]:
    """``(bias, opening)`` the assistant estimates from constructed operator poses: the
    library's template less ``rest`` in the rest window, less ``hold`` from then on."""
    template = next(iter(templates.values()))
    assistant = AnalyticAssistant(templates)
    assistant.reset(env)
    dt = env.config.control_dt
    for k in range(1, round(OPENING_WINDOW[1] / dt) + 1):
        t = k * dt
        offset = rest if t <= REST_WINDOW[1] else hold
        assistant._squeeze_offset(env, t, template.at(t) - offset, {})
    return assistant.bias, assistant.opening


def test_the_opening_is_read_finger_by_finger_at_rest_and_along_the_pinch_in_the_hold(
    templates,
) -> None:
    """The rest and hold estimates on constructed poses (no person's own pinch in them): a
    bias opens both fingers at rest and in the hold; an index (or a thumb) opened at rest
    alone is a person's own rest; a hold short of the template by more than its closing
    from rest is a weak grip; a pinch closer than the library's opens nothing."""
    env = make(duration=1.2).unwrapped
    env.reset(seed=0)
    d = pinch_direction()
    index, thumb = np.zeros(10), np.zeros(10)
    for name in ("index_mcp", "index_pip"):
        index[joint_index(name)] = d[joint_index(name)]
    thumb[joint_index("thumb_flexion")] = d[joint_index("thumb_flexion")]
    zero = np.zeros(10)
    bias = DEFAULT_STRENGTHS["biased_calibration"]
    weak = DEFAULT_STRENGTHS["weak_grip"]
    # a bias: both fingers opened at rest and in the hold; undone once, not twice
    b, o = _estimate(templates, env, bias * d, bias * d)
    assert b == pytest.approx(bias, abs=1e-9) and o == pytest.approx(bias, abs=1e-9)
    # one finger opened at rest (a person's own rest, a larger hand's index) is no bias, and
    # a hold at the template's, closing more than the library's from there, no opening
    for finger in (index, thumb):
        assert _estimate(templates, env, 0.24 * finger, zero) == (0.0, 0.0)
    # a weak grip: the hold opened along the pinch, the rest the library's
    b, o = _estimate(templates, env, zero, weak * d)
    assert b == 0.0 and o == pytest.approx(weak - CLOSING_DEADBAND, abs=1e-9)
    # a pinch closer than the library's is a person's own: nothing opened, nothing closed
    assert _estimate(templates, env, zero, -weak * d) == (0.0, 0.0)


def test_with_the_phase_recogniser_the_assistant_follows_an_intent_switch(templates) -> None:
    from ias_gym.assist.recogniser_registry import make_recogniser
    from ias_gym.skills import SkillDB
    from ias_gym.skills.transfer import shipped_skill_db

    with SkillDB(shipped_skill_db(), readonly=True) as db:
        recogniser = make_recogniser("phase", db)
    env = make(skill="lift_hold", switch_to="tilt_left", switch_time=2.2, duration=3.5)
    assistant = AnalyticAssistant(templates, recogniser)
    result = run_session(env, assistant, 0)
    assert sum(assistant.posterior().values()) == pytest.approx(1.0)
    top = result.top_skill
    assert top[150] == "lift_hold"  # before the switch: the pinch-lift-hold
    # within 0.5 s of the switch the recogniser names the new intent (it may call the late
    # tilt unknown afterwards: no library session tilts that late)
    assert "tilt_left" in top[220:270]
    # the oracle follows at once: the step whose time crosses the switch, 2 steps
    oracle = run_session(env, AnalyticAssistant(templates), 0)
    assert oracle.switch_latency_s == pytest.approx(0.02)
    assert oracle.top_skill[-1] == "tilt_left"


class _Constant:
    def __init__(self, value: float) -> None:
        self.value = value

    def reset(self, env) -> None:
        pass

    def act(self, env) -> np.ndarray:
        return np.full(10, self.value)

    def posterior(self) -> dict[str, float]:
        return {}


def test_intervention_is_offsets_over_the_operators_motion() -> None:
    env = make(skill="lift_hold", duration=1.0)
    none = run_session(env, None, 0)
    const = run_session(env, _Constant(0.05), 0)
    assert none.intervention == 0.0
    # the operator's motion over the same steps, from its targets
    u = env.unwrapped
    env.reset(seed=0)
    thetas = []
    for _ in range(len(const.times)):
        thetas.append(env.step(np.full(10, 0.05))[4]["operator_theta"])
    motion = np.mean(np.abs(np.array(thetas) - thetas[0]).sum(axis=1))
    expected = 10 * 0.05 * u.config.action_scale / motion
    assert const.intervention == pytest.approx(expected, rel=1e-9)


def test_cli_evaluate_json_keys(capsys, monkeypatch) -> None:
    from ias_gym.cli import assist_commands as cli_assist
    from ias_gym.cli import main
    from ias_gym.skills.transfer import shipped_skill_db

    # the recognition metrics themselves are tests/test_assist_recognition.py's (recording
    # their sessions takes ~40 s); here: that they reach the JSON for these persons
    calls = []

    def metrics(db, persons, episodes, seed):
        calls.append(persons)
        return dict.fromkeys(cli_assist.RECOGNITION_KEYS, 0.5)

    monkeypatch.setattr(cli_assist, "_recognition_metrics", metrics)

    argv = ["assist", "evaluate", "--db", str(shipped_skill_db()), "--persons", PERSON]
    # the observation assistant has no oracle: the true intent is no observation
    assert main([*argv, "--recogniser", "oracle", "--episodes", "1"]) == 2
    argv += ["--assistant", "analytic", "--recogniser", "oracle"]
    code = main([*argv, "--impairment", "none", "--episodes", "1", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in (
        "recog_acc_at_33",
        "recog_acc_at_60",
        "time_to_recognise_s",
        "false_trigger_rate",
        "unknown_auroc",
    ):
        assert out[key] == 0.5
    assert calls == [[PERSON]]
    row = out["by_impairment"]["none"]
    assert set(row) >= {"success_unassisted", "success_assisted", "intervention"}
    # one session, judged or left out for want of a reference (a knife edge on this CPU's
    # calibration); judged, the unimpaired operator against itself succeeds
    assert row["sessions"] + row["excluded"] == 1
    if row["sessions"]:
        assert row["success_unassisted"] == 1.0
    else:
        assert row["success_unassisted"] is None
    assert main([*argv, "--impairment", "palsy", "--episodes", "1"]) == 2
    assert main([*argv, "--impairment", "tremor:hz=2", "--episodes", "1"]) == 2


@pytest.mark.realtime
@pytest.mark.usefixtures("no_python_can_warnings", "no_gc_pauses")
def test_the_assistant_runs_on_the_can_glove(channel: str, templates) -> None:
    from ias_gym.hardware import GloveEmulator, GloveHardwareEnv

    with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=0.2):
        env = GloveHardwareEnv(channel=channel, watchdog_timeout=0.2, skill="lift_hold")
        try:
            env.reset(seed=0)
            assistant = AnalyticAssistant(templates)
            assistant.reset(env)
            for _ in range(30):
                action = assistant.act(env)
                assert action.shape == (10,) and np.all(np.abs(action) <= 1.0)
                theta = env._theta.copy()
                *_, info = env.step(action)
                assert not info["fault"]
            # the offsets reached the hand: targets = operator + scale x action (clipped)
            lo, hi = env._ctrl_lo, env._ctrl_hi
            target = np.clip(env._theta + env.config.action_scale * action, lo, hi)
            np.testing.assert_allclose(env.data.ctrl[env._act], target)
            assert 0.0 <= assistant.g and theta.shape == (10,)
        finally:
            env.close()


def test_cli_demo_writes_both_sessions_side_by_side(tmp_path: Path) -> None:
    import imageio.v3 as iio

    from ias_gym.cli import main

    video = tmp_path / "assist.mp4"
    argv = ["assist", "demo", "--video", str(video), "--duration", "0.2"]
    assert main([*argv, "--recogniser", "oracle"]) == 0
    frames = iio.imread(video)
    assert frames.shape == (11, 360, 960, 3)  # 20 steps and the reset, every second; two renders
    # nothing is overwritten silently
    assert main([*argv, "--recogniser", "oracle"]) == 2
    with pytest.raises(SystemExit) as bad:  # argparse's usage error
        main([*argv, "--duration", "0"])
    assert bad.value.code == 2
    # the observation assistant too (a stopped skill), and a recogniser it cannot take
    other = [*argv[:3], str(tmp_path / "stops.mp4"), *argv[4:], "--assistant", "observation"]
    assert main([*other, "--impairment", "stops:at=0.4", "--recogniser", "oracle"]) == 2
    assert main([*other, "--impairment", "stops:at=0.4"]) == 0
    assert iio.imread(tmp_path / "stops.mp4").shape == (11, 360, 960, 3)
