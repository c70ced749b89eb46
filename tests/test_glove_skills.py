"""Glove skills: skills after the pinch-lift, any person id, soft-finger pads."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.assist.sessions import HELD_FROM
from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.envs.glove_grasp_rewards import REWARD_TERMS
from ias_gym.errors import InputError
from ias_gym.glove import skills as glove_skills
from ias_gym.glove.device import ReachPinchLift, ReachPinchLiftTimings, SimulatedGlove
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.operator import FromPreShape, pen_operator
from ias_gym.glove.skills import (
    SKILL_DESCRIPTIONS,
    SKILLS,
    SkillStyle,
    check_skill,
    skill_motion_time,
    skill_object_target,
    skill_start_time,
)
from ias_gym.grasp.wrench_matrix import wrench_matrix
from ias_gym.sim.scene_constants import glove_pen_radius
from ias_gym.sim.soft_finger import (
    FingerContacts,
    pinch_null_basis,
    soft_contact_intensities,
    soft_finger_cone_margin,
    soft_wrench_matrix,
)
from ias_gym.skills import SkillDB
from ias_gym.skills.glove_session import GloveSkillModelRecorder
from ias_gym.skills.record import record_skills_spec
from tests.closed_loop import perturbed_starts, typical_person

ENV_ID = "IAS-GloveGrasp-v0"
#: Persons of the fixture: one the code ships (p2) and one it never saw before (q17).
PERSONS = ("p2", "q17")
ZERO = np.zeros(10, dtype=np.float32)


def _rollout(
    env: gym.Env[np.ndarray, np.ndarray], seed: int = 0, options: dict | None = None
) -> dict[str, np.ndarray]:
    """One teleop episode: the pen's pose per step and whether both fingers held it."""
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, GloveGraspEnv)
    env.reset(seed=seed, options=options)
    pose, held, success = [], [], []
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(ZERO)
        position, rpy = unwrapped.physics.pen_pose()
        pose.append(np.concatenate([position, rpy]))
        held.append((info["index_contact"], info["thumb_contact"]))
        success.append(info["is_success"])
        done = terminated or truncated
    return {
        "time": unwrapped.config.control_dt * np.arange(1, len(pose) + 1),
        "pose": np.array(pose),
        "held": np.array(held, dtype=bool).reshape(-1, 2),
        "success": np.array(success),
        "terminated": np.array(terminated),
    }


def _held(run: dict[str, np.ndarray]) -> bool:
    """The pen stayed in the hand from the lift's start to the end: at every step a finger
    touches it, and both do at all but 1 % of the steps (a pad may part from the pen for a
    step while the wrist turns; the thumb below it still carries it)."""
    contacts = run["held"][run["time"] >= HELD_FROM - 1e-9]
    both = contacts.all(axis=1)
    return bool(contacts.any(axis=1).all() and both.mean() >= 0.99)


def _first_start(env: gym.Env[np.ndarray, np.ndarray], seed: int = 0) -> dict | None:
    """The first of the seed's perturbed starts (closed_loop.py): the seed's own, or in the
    perturbation mode one moved by ~1e-9, as another machine would."""
    return next(perturbed_starts(env, seed, n=0))


@pytest.fixture(scope="module")
def runs() -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """Every skill performed once by each of :data:`PERSONS` (seed 0, its first start)."""
    out = {}
    for person in PERSONS:
        for skill in SKILLS:
            env = gym.make(ENV_ID, person_id=person, skill=skill)
            out[person, skill] = _rollout(env, options=_first_start(env))
            env.close()
    return out


def _added_motion(
    runs: dict[tuple[str, str], dict[str, np.ndarray]],
    person: str,
    skill: str,
    meaning: str | None = None,
    lag: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """What ``skill`` adds to holding the pen from its start over the longer motion time of
    ``skill`` and ``meaning`` (:func:`skill_motion_time`) and 0.2 s: ``(performed, meant)``,
    each ``(T, 2)``: the pen's height [mm] and see-saw tilt (yaw) [deg] in the person's run
    of ``skill`` minus those in their ``lift_hold`` (the same episode up to the start, so
    the pinch-lift's own motion cancels), and the same difference of what ``meaning``
    (default: ``skill``) and ``lift_hold`` mean for the person (:func:`skill_object_target`
    with their style), ``lag`` [s] later."""
    style = SkillStyle.sample(person)
    time = runs[person, "lift_hold"]["time"]
    start = skill_start_time(skill, person)
    motion = max(skill_motion_time(s, style.speed) for s in (skill, meaning or skill))
    end = start + motion + 0.2
    window = (time >= start) & (time <= end)
    pose = runs[person, skill]["pose"] - runs[person, "lift_hold"]["pose"]
    meant = np.array(
        [
            np.subtract(
                skill_object_target(meaning or skill, float(t) - lag, style),
                skill_object_target("lift_hold", float(t) - lag, style),
            )
            for t in time[window]
        ]
    )
    scale = np.array([1e3, math.degrees(1.0)])
    return pose[window][:, [1, 5]] * scale, meant * scale


def test_skills_are_named_described_and_checked() -> None:
    assert len(SKILLS) >= 5 and len(set(SKILLS)) == len(SKILLS)
    assert set(SKILL_DESCRIPTIONS) == set(SKILLS)
    assert check_skill("tilt_left") == "tilt_left"
    for bad in ("nope", "", None, "Tilt_Left"):
        with pytest.raises(InputError, match="choose one of lift_hold, seesaw_slow"):
            check_skill(bad)
    with pytest.raises(InputError, match="skill 'spin' is not a glove skill"):
        gym.make(ENV_ID, skill="spin")


def test_a_person_style_is_deterministic_in_the_id_across_processes() -> None:
    """The same id gives the same person and style in another process with another hash
    seed (Python's ``hash()`` would not); two ids differ."""
    code = (
        "import json; from ias_gym.glove.skills import SkillStyle;"
        "from ias_gym.glove.hand import PersonParams;"
        "print(json.dumps([repr(SkillStyle.sample('q17')), PersonParams.sample('q17').to_dict()]))"
    )
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=Path(__file__).resolve().parents[1],
    )
    style, person = json.loads(out.stdout)
    assert style == repr(SkillStyle.sample("q17"))
    assert person == PersonParams.sample("q17").to_dict()
    assert SkillStyle.sample("q17") != SkillStyle.sample("anna")
    assert PersonParams.sample("q17") != PersonParams.sample("anna")
    with pytest.raises(InputError, match="not a valid id"):
        SkillStyle.sample("../x")


@pytest.mark.closed_loop
@pytest.mark.parametrize("operator", ["script", "closed_loop"])
def test_the_default_episode_is_the_old_pinch_lift(operator: str) -> None:
    """Without a skill the plan is the old pinch-lift (its default timings and 2 N pinch):
    from the seed's start and from nearby ones (closed_loop.py) the open-loop person's glove
    reads that script at every step, bit for bit (the person in the loop runs the same plan),
    every observation is finite, every reward is the sum of its terms as the env's docstring
    defines them from the step's own info, and the episode runs its 4 s (no drop) and ends
    with the pen lifted in both pads."""
    env = gym.make(ENV_ID, operator=operator)
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, GloveGraspEnv)
    cfg = unwrapped.config
    assert cfg.skill is None and unwrapped.skill_start is None
    person = unwrapped.person
    old = pen_operator(person, glove_pen_radius())
    assert old.timings == ReachPinchLiftTimings() and old.pinch_force == 2.0
    script = FromPreShape(old)
    for options in perturbed_starts(env, seed=3, n=2):
        obs, info = env.reset(seed=3, options=options)
        glove = unwrapped.glove
        assert np.isfinite(obs).all() and info["reward_lift"] == 0.0
        if operator == "closed_loop":
            assert unwrapped.operator is not None
            plan = unwrapped.operator.plan
            assert isinstance(plan, ReachPinchLift) and plan.timings == old.timings
        done, steps = False, 0
        while not done:
            obs, reward, terminated, truncated, info = env.step(ZERO)
            done = terminated or truncated
            steps += 1
            # The glove read the old script at this step's time (read k at k / 100 s).
            assert isinstance(glove, SimulatedGlove) and glove.last_theta is not None
            if operator == "script":
                np.testing.assert_array_equal(glove.last_theta, script(steps / 100.0))
            assert np.isfinite(obs).all() and not info["sim_unstable"] and not info["fault"]
            terms = {name: info[f"reward_{name}"] for name in REWARD_TERMS}
            assert reward == pytest.approx(sum(terms.values()), abs=1e-12)
            dz = info["pen_height"]
            lift = cfg.lift_weight * min(max(dz / cfg.lift_height, 0.0), 1.0)
            assert terms["lift"] == pytest.approx(lift, abs=1e-12)
            both = info["index_contact"] and info["thumb_contact"]
            assert terms["pinch"] == cfg.contact_weight * both and terms["effort"] == 0.0
        assert steps == 400 and not terminated, options is None
        assert info["is_success"] and both, options is None
    env.close()


@pytest.mark.closed_loop
def test_skills_share_the_pinch_lift_then_differ(
    runs: dict[tuple[str, str], dict[str, np.ndarray]],
) -> None:
    """Before ``skill_start_time`` every skill of a person is the same episode (bit for
    bit); after it the pen moves differently."""
    for person in PERSONS:
        first = runs[person, SKILLS[0]]
        for skill in SKILLS[1:]:
            run = runs[person, skill]
            start = skill_start_time(skill, person)
            assert 1.6 <= start <= 1.9
            before = run["time"] < start
            np.testing.assert_array_equal(run["pose"][before], first["pose"][before])
            after = run["time"] > start + 0.5
            assert np.abs(run["pose"][after] - first["pose"][after]).max() > 1e-3


@pytest.mark.closed_loop
def test_a_new_person_gives_the_same_episode_twice(
    runs: dict[tuple[str, str], dict[str, np.ndarray]],
) -> None:
    """A person id never seen before (q17) is a deterministic person: a second env of the
    same id and skill repeats the episode bit for bit; another id (p2) moves the pen
    otherwise."""
    env = gym.make(ENV_ID, person_id="q17", skill="seesaw_slow")
    again = _rollout(env, options=_first_start(env))
    env.close()
    np.testing.assert_array_equal(again["pose"], runs["q17", "seesaw_slow"]["pose"])
    other = runs["p2", "seesaw_slow"]["pose"]
    assert np.abs(again["pose"] - other).max() > 1e-3


def _unexplained(
    runs: dict[tuple[str, str], dict[str, np.ndarray]], person: str, skill: str, meaning: str
) -> float:
    """How much of what ``skill`` adds to holding the pen (:func:`_added_motion`) the
    motion ``meaning`` means leaves unexplained: ``|performed - g meant| / |performed|``,
    the least over a reaction lag of 0-0.2 s and a gain ``g`` in [0.5, 1.5] (least squares,
    clipped). 0: the performed motion is the meant one; 1: nothing of it."""
    best = np.inf
    for lag in np.arange(0.0, 0.21, 0.02):
        done, want = (a.ravel() for a in _added_motion(runs, person, skill, meaning, lag))
        gain = float(np.clip(done @ want / (want @ want), 0.5, 1.5))
        best = min(best, float(np.linalg.norm(done - gain * want) / np.linalg.norm(done)))
    return best


@pytest.mark.closed_loop
def test_each_skill_moves_the_pen_as_it_means(
    runs: dict[tuple[str, str], dict[str, np.ndarray]],
) -> None:
    """What a skill adds to holding the pen is explained better by what that skill means
    for the person (:func:`skill_object_target` with their style) than by what any other
    skill means (:func:`_unexplained`: up to a reaction lag and a gain, since the pads'
    compliance and the person's corrections attenuate a fast see-saw to 0.6-0.8 x the
    wrist's intent and sink the pen by 2-3 mm). A skill swapped, mirrored or left out fails
    it. Both motions are compared over the longer of the two skills' motion times: after
    its motion a pen may turn on about the pads' pinch axis, which is the see-saw axis and
    held only by the pads' torsional friction (up to 10 deg after a fast see-saw with
    another trained calibration); that is left to the held test. ``lift_hold`` adds nothing
    by definition; its pen's tilt stays within half of the smallest amplitude any other
    skill means for the person."""

    moving = [s for s in SKILLS if s != "lift_hold"]
    for person in PERSONS:
        for skill in moving:
            own = _unexplained(runs, person, skill, skill)
            others = {o: _unexplained(runs, person, skill, o) for o in moving if o != skill}
            nearest = min(others, key=others.__getitem__)
            assert own < others[nearest], (person, skill, own, nearest, others)
        hold = runs[person, "lift_hold"]
        tilt = hold["pose"][hold["time"] >= skill_start_time("lift_hold", person), 5]
        smallest = min(
            np.ptp(_added_motion(runs, person, s)[1][:, 1]) for s in moving if s != "lift_place"
        )
        assert math.degrees(np.ptp(tilt)) < 0.5 * smallest, person


@pytest.mark.closed_loop
def test_the_pen_stays_held_for_every_skill(
    runs: dict[tuple[str, str], dict[str, np.ndarray]],
) -> None:
    """The fingers hold the pen from the lift's start to the end (:func:`_held`) and the
    env's success holds at the end (lifted; lift_place: put back within 5 mm of its start).
    Before the lift the support carries the pen, and a pad may leave it for a few steps as
    the close settles (q17's lift_hold with another trained calibration, 0.70-0.74 s)."""
    for (person, skill), run in runs.items():
        assert not run["terminated"], (person, skill)
        assert _held(run), (person, skill)
        assert run["success"][-1], (person, skill)
        if skill == "lift_place":
            assert abs(run["pose"][-1, 1]) < 0.005 and run["pose"][:, 1].max() > 0.03
        else:
            assert run["pose"][-1, 1] > 0.03


@pytest.mark.closed_loop
def test_a_typical_person_mostly_holds_the_pen_from_perturbed_starts() -> None:
    """A typical person of the population (closed_loop.py) does every skill from the seed's
    start and nearby ones: the pen held from the lift to the end and the env's success, in
    most of the rollouts (more than half), and every rollout that lost the pen says so (the
    episode not a success). Not in all: which of a person's sessions succeed depends on the
    trained calibration's bits. With a calibration trained under seed 5, as accurate as the
    default one (1.07 against 0.99 deg RMS on held-out poses), this person tips the pen off
    the thumb in tilt_left and seesaw_fast from every start (12 of 18). The population's
    rate is measured by train/completion_table.py; an operator or a pinch that is broken
    drops the pen in nearly all."""
    outcomes = []
    for skill in SKILLS:
        env = gym.make(ENV_ID, person_id=typical_person(), skill=skill)
        for options in perturbed_starts(env, seed=1):
            run = _rollout(env, seed=1, options=options)
            held = _held(run)
            outcomes.append(held and bool(run["success"][-1]))
            if run["terminated"]:
                assert not run["success"][-1], (skill, options is None)
        env.close()
    assert sum(outcomes) > len(outcomes) / 2, outcomes


def test_soft_finger_skill_model_during_a_skill() -> None:
    """While the pen is held: W is 6 x 8 of rank 6, N (the squeeze and the opposed
    torsions) spans null(W), W c is the fingers' net wrench on the pen (force and moment,
    MuJoCo's), and every finger-pen contact lies in its friction cone."""
    env = gym.make(ENV_ID, person_id="q17", skill="seesaw_fast")
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, GloveGraspEnv)
    recorder = GloveSkillModelRecorder()
    env.reset(seed=0)
    recorder.sample(unwrapped)
    p = unwrapped.physics
    held = 0
    for _ in range(400):
        _, _, terminated, truncated, _ = env.step(ZERO)
        recorder.sample(unwrapped)
        contacts = p.finger_contacts(unwrapped.contact_pass)
        W, active = p.wrench_matrix(contacts)
        c = p.contact_intensities(contacts)
        assert W.shape == (6, 8) and c.shape == (8,)
        if active.all():
            held += 1
            assert np.linalg.matrix_rank(W) == 6
            N = pinch_null_basis(W, contacts)
            assert N is not None
            np.testing.assert_allclose(W @ N, 0.0, atol=1e-12)
            np.testing.assert_allclose(N.T @ N, np.eye(2), atol=1e-12)
            net = np.concatenate([contacts.force.sum(axis=0), contacts.moment.sum(axis=0)])
            np.testing.assert_allclose(W @ c, net, atol=1e-9)
            # A finger with one MuJoCo contact is that contact: inside its condim-4 cone.
            margin = soft_finger_cone_margin(c, contacts.friction)
            assert (margin[contacts.count == 1] > -1e-9).all()
        if terminated or truncated:
            break
    env.close()
    assert held > 250
    model = recorder.model()
    model.validate()
    assert model.c.shape == (401, 8) and model.f_int.shape == (401, 2)
    both = model.touching.all(axis=1)
    assert np.isfinite(model.f_int[both]).all() and np.isnan(model.f_int[~both]).all()
    assert (model.f_int[both, 0] > 0).all()  # squeezing


def _contacts(points: np.ndarray, normals: np.ndarray, torsion: np.ndarray) -> FingerContacts:
    frames = []
    for n in normals:
        t1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
        t1 /= np.linalg.norm(t1)
        frames.append(np.stack([n, t1, np.cross(t1, n)]))
    return FingerContacts(
        active=np.array([True, True]),
        points=points,
        frames=np.array(frames),
        force=np.zeros((2, 3)),
        moment=np.zeros((2, 3)),
        count=np.ones(2, dtype=np.int64),
        torsion=torsion,
        friction=np.array([[0.25, 0.03], [0.25, 0.03]]),
    )


def test_soft_pinch_wrench_matrix_and_internal_forces() -> None:
    """An antipodal pinch of a 1 cm pen: the hard-finger W has rank 5 (no moment about the
    chord), the soft-finger W (eq. 16 + [0; n]) rank 6; its null space is exactly the
    squeeze and the opposed torsions; c_tau enters W c as a moment along the normal."""
    r = 0.01
    points = np.array([[0.0, r, 0.0], [0.0, -r, 0.0]])  # index above, thumb below
    contacts = _contacts(points, -points / r, np.zeros(2))
    assert np.linalg.matrix_rank(wrench_matrix(points, contacts.frames)) == 5
    W = soft_wrench_matrix(contacts, np.zeros(3))
    assert W.shape == (6, 8) and np.linalg.matrix_rank(W) == 6
    np.testing.assert_array_equal(W[:, 3], [0, 0, 0, *contacts.frames[0, 0]])
    N = pinch_null_basis(W, contacts)
    assert N is not None
    s = 1.5  # each finger squeezes with 1.5 N and twists by 2 mN m the other way
    c = np.array([s, 0, 0, 0.002, s, 0, 0, 0.002])
    np.testing.assert_allclose(W @ c, 0.0, atol=1e-15)
    np.testing.assert_allclose(N.T @ c, [math.sqrt(2) * s, math.sqrt(2) * 0.002], atol=1e-12)
    # One finger twisting alone is an external moment about the chord (paper y here).
    one = np.array([0, 0, 0, 0.002, 0, 0, 0, 0])
    np.testing.assert_allclose(W @ one, [0, 0, 0, 0, -0.002, 0], atol=1e-15)
    c_from = soft_contact_intensities(_contacts(points, -points / r, np.array([0.002, 0.0])))
    assert c_from[3] == 0.002 and c_from[7] == 0.0
    # The cone: |t| / mu and |tau| / mu_tau inside the normal force (elliptic).
    friction = np.array([[0.25, 0.03], [0.25, 0.03]])
    inside = np.array([1.0, 0.15, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0])
    outside = np.array([1.0, 0.2, 0.0, 0.02, 1.0, 0.0, 0.0, 0.0])
    assert (soft_finger_cone_margin(inside, friction) > 0).all()
    assert soft_finger_cone_margin(outside, friction)[0] < 0


def test_record_names_the_skill_and_the_person(tmp_path: Path) -> None:
    db = tmp_path / "skills.db"
    ids = record_skills_spec(
        ENV_ID, "teleop", 1, db, seed=0, progress=False, person_id="x9", skill="tilt_right"
    )
    with SkillDB(db) as database:
        skill = database.get(ids[0])
    assert skill.name == "tilt_right" and skill.person_id == "x9"
    assert skill.env_kwargs == {"person_id": "x9", "skill": "tilt_right"}
    assert skill.model.c.shape[1] == 8 and skill.model.f_int.shape[1] == 2
    assert skill.is_success
    # The stored skill start: the same function, from the stored kwargs.
    assert skill_start_time(skill.env_kwargs["skill"], skill.person_id) == pytest.approx(
        glove_skills.SKILL_TIMINGS.lift
        - glove_skills.SKILL_TIMINGS.reach
        + SkillStyle.sample("x9").delay
    )
    with pytest.raises(InputError, match="not a glove skill; choose one of"):
        record_skills_spec(ENV_ID, "teleop", 1, db, progress=False, skill="wave")
    with pytest.raises(InputError, match="--skill is for glove envs"):
        record_skills_spec("IAS-PenRotate-v0", "expert", 1, db, progress=False, skill="tilt_left")


def test_cli_skill_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--skill``'s help lists the skills; a wrong name is one line naming the valid ones
    (exit 2, nothing stored)."""
    from ias_gym.cli import main

    with pytest.raises(SystemExit):
        main(["skills", "record", "--help"])
    # argparse wraps the help text: compare without line breaks and indentation
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--skill NAME" in help_text and ", ".join(SKILLS) in help_text
    db = tmp_path / "s.db"
    code = main(["skills", "record", "--env", ENV_ID, "--policy", "teleop", "--skill", "wave",
                 "--db", str(db), "--no-progress"])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "'wave' is not a glove skill; choose one of " + ", ".join(SKILLS) in err[0]
    assert not db.exists()
