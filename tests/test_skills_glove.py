"""Glove sessions of IAS-GloveGrasp-v0 recorded as skills: sampler, physics, database, CLI."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.cli.skills_commands import add_skills_commands
from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.errors import InputError
from ias_gym.glove.profile import DEFAULT_GLOVE_ID
from ias_gym.grasp.wrench_matrix import wrench_matrix
from ias_gym.sim.glove_contacts import GlovePenPhysics
from ias_gym.sim.glove_scene import (
    FINGER_ABOVE,
    FINGER_GEOMS,
    FINGER_TIPS,
    INDEX_GEOMS,
    THUMB_GEOMS,
    load_glove_scene,
)
from ias_gym.sim.pen_hand import mj_to_paper
from ias_gym.sim.soft_finger import FingerContacts, squeeze_null_vector
from ias_gym.skills import (
    SkillDB,
    SkillDBError,
    SkillModel,
    glove_session_source,
)
from ias_gym.skills.glove_session import GloveSkillModelRecorder
from ias_gym.skills.record import record_skills_spec

ENV_ID = "IAS-GloveGrasp-v0"
STEPS = 400  # 4 s of 10 ms steps
SEEDS = (0, 1)
_SCENE = load_glove_scene()
#: The scene's gravity in the paper frame (y is up) [m/s^2] and its pen's mass [kg] (1 N).
GRAVITY = mj_to_paper(_SCENE.opt.gravity)
PEN_MASS = float(_SCENE.body("pen").mass[0])


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[int]]:
    path = tmp_path_factory.mktemp("glove") / "skills.db"
    ids = record_skills_spec(ENV_ID, "teleop", len(SEEDS), path, seed=SEEDS[0], progress=False)
    return path, ids


def _held(model: SkillModel, infos: dict[str, np.ndarray]) -> np.ndarray:
    """Samples where the pen is lifted off its support (the env's success) by both fingers."""
    return np.asarray(infos["is_success"] & model.touching.all(axis=1))


def test_glove_sessions_are_stored_with_their_provenance(
    recorded: tuple[Path, list[int]],
) -> None:
    path, ids = recorded
    with SkillDB(path) as db:
        summaries = db.list_skills(task=ENV_ID)
        assert [s.id for s in summaries] == ids
        for seed, summary in zip(SEEDS, summaries, strict=True):
            # A glove session: the glove's id in the source, the env's person, the seed.
            assert summary.source == f"glove:{DEFAULT_GLOVE_ID}"
            assert (summary.person_id, summary.seed) == ("p1", seed)
            assert summary.name == f"{ENV_ID} glove:{DEFAULT_GLOVE_ID} p1 seed {seed}"
            assert summary.length == STEPS and summary.is_success
            skill = db.get(summary.id)
            demo, model = skill.demonstration, skill.model
            assert demo.observations.shape == (STEPS + 1, 39)
            assert not demo.actions.any()  # teleop: the glove alone drives the hand
            # Soft fingers: 4 intensities each, G exists, two internal forces.
            assert not model.is_pinch
            assert model.touching.shape == model.sliding.shape == (STEPS + 1, 2)
            assert model.c.shape == model.c_h.shape == (STEPS + 1, 8)
            assert model.f_int.shape == (STEPS + 1, 2) and model.f_ext.shape == (STEPS + 1, 6)
            assert not model.sliding.any()
            np.testing.assert_allclose(np.diff(model.time), 0.01, atol=1e-9)


def test_pen_trajectory_is_the_lift_in_the_paper_frame(recorded: tuple[Path, list[int]]) -> None:
    path, ids = recorded
    with SkillDB(path) as db:
        for skill_id in ids:
            skill = db.get(skill_id)
            model, demo = skill.model, skill.demonstration
            lift = model.pen_position[:, 1]  # paper y = up
            assert lift[0] == pytest.approx(0.0, abs=1e-6)
            assert lift.max() >= 0.03 and lift[-1] >= 0.03  # the env's success: 30 mm up
            # The observation's pen block (MuJoCo world) is the same motion: paper
            # (x, y, z) = MuJoCo (x, z, -y). Velocities are read from the same qvel; the
            # observed position is from the forward pass before the step's last 1 ms.
            world = demo.observations[:, OBSERVATION["pen_velocity"]]
            np.testing.assert_array_equal(
                model.pen_velocity, np.column_stack([world[:, 0], world[:, 2], -world[:, 1]])
            )
            world = demo.observations[:, OBSERVATION["pen_position"]]
            np.testing.assert_allclose(
                model.pen_position,
                np.column_stack([world[:, 0], world[:, 2], -world[:, 1]]),
                atol=5e-4,
            )
            np.testing.assert_allclose(lift, demo.infos["pen_height"], atol=2e-4)


def test_contact_schedule_and_intensities(recorded: tuple[Path, list[int]]) -> None:
    path, ids = recorded
    with SkillDB(path) as db:
        for skill_id in ids:
            skill = db.get(skill_id)
            model, infos = skill.model, skill.demonstration.infos
            # The same touch as the env's force display reports.
            np.testing.assert_array_equal(model.touching[:, 0], infos["index_contact"])
            np.testing.assert_array_equal(model.touching[:, 1], infos["thumb_contact"])
            both = np.asarray(model.touching.all(axis=1))
            pinch = model.time[both][0]  # the pinch closes 0.7 s into the episode
            assert 0.3 <= pinch <= 0.8
            assert both[model.time >= pinch].all()  # from the pinch on, both touch: held
            assert not model.touching[0].any()
            # c: finite, zero for a finger that does not touch, pushing when it does.
            assert np.isfinite(model.c).all()
            touching = np.repeat(model.touching, 4, axis=1)
            assert not model.c[~touching].any()
            normals = model.c[:, 0::4]
            assert (normals[model.touching] >= 0).all()
            assert normals[both].sum(axis=1).min() > 0.5  # [N]: a squeeze, not a graze


def test_held_pen_is_in_equilibrium(recorded: tuple[Path, list[int]]) -> None:
    """W c + m g = m a for the pen held off its support (docs/NOTES.md: W c holds the pen up).

    a from central differences of the recorded velocity; the contact forces are those of
    the step's last 1 ms, so the residual measured is up to 0.073 N (median 0.03 N) of the
    1 N weight. A wrong sign of c, or a finger left out, misses by about 1 N.
    """
    path, ids = recorded
    weight = PEN_MASS * float(np.linalg.norm(GRAVITY))
    with SkillDB(path) as db:
        for skill_id in ids:
            skill = db.get(skill_id)
            model = skill.model
            held = _held(model, dict(skill.demonstration.infos))
            held[[0, -1]] = False  # no central difference there
            assert held.sum() > 150  # the last 2 s
            a = np.gradient(model.pen_velocity, model.time, axis=0)
            residual = model.f_ext[:, :3] + PEN_MASS * GRAVITY - PEN_MASS * a
            assert np.linalg.norm(residual[held], axis=1).max() < 0.1 * weight
            wrong = -model.f_ext[:, :3] + PEN_MASS * GRAVITY - PEN_MASS * a
            assert np.linalg.norm(wrong[held], axis=1).min() > 1.0 * weight


def test_squeeze_is_the_pinch_force(recorded: tuple[Path, list[int]]) -> None:
    """f_int[0] = N_1^T c (eqs. 7, 10), the soft pinch's squeeze: positive, of the operator's
    pinch force; f_int[1] (the opposed torsions) is small [N m].

    Measured while held: f_int 0.60-1.18 N, 0.52-0.65 of the env's pinch force (the sum
    of the pads' normal forces, 1.4-1.8 N).
    """
    path, ids = recorded
    with SkillDB(path) as db:
        for skill_id in ids:
            skill = db.get(skill_id)
            model, infos = skill.model, skill.demonstration.infos
            both = model.touching.all(axis=1)
            f_int = model.f_int[:, 0]
            # Defined exactly where both fingers touch; c_h = N f_int with an orthonormal N.
            np.testing.assert_array_equal(np.isfinite(model.f_int).all(axis=1), both)
            np.testing.assert_array_equal(np.isfinite(model.c_h).all(axis=1), both)
            np.testing.assert_allclose(
                np.linalg.norm(model.c_h[both], axis=1),
                np.linalg.norm(model.f_int[both], axis=1),
                rtol=1e-12,
            )
            # The second internal force (opposed torsions with the axial shear that balances
            # them in the glove's 110-degree pinch): measured |f_int[1]| <= 0.43.
            assert np.abs(model.f_int[both, 1]).max() < 1.0
            assert (f_int[both] > 0).all()  # squeezing is positive, from the first touch on
            held = _held(model, dict(infos))
            assert 0.4 < f_int[held].min() and f_int[held].max() < 2.5  # [N]
            ratio = f_int[held] / infos["pinch_force"][held]
            assert 0.3 < ratio.min() and ratio.max() < 1.0
            summary = model.summary()
            assert summary["grip_transform_defined_fraction"] == pytest.approx(both.mean())
            assert summary["f_int_range"][0][0] > 0


def test_sampler_matches_mujoco_at_every_step() -> None:
    """The sampled f_ext is the fingers' net force on the pen to 1e-3 N, the moment of W c
    is the exact one (MuJoCo's, incl. the pads' torsion, now a column of the soft-finger W)
    to 1e-9 N m, and the exact moment obeys Euler's equation (measured: 3e-4 N, 2e-17 N m,
    2.4e-5 N m; the hard-finger W missed the moment by up to 1.8e-3 N m)."""
    env = gym.make(ENV_ID)
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, GloveGraspEnv)
    recorder = GloveSkillModelRecorder()
    env.reset(seed=2)
    recorder.sample(unwrapped)
    fingers = dict(zip(FINGER_GEOMS, (INDEX_GEOMS, THUMB_GEOMS), strict=True))
    physics = GlovePenPhysics(
        unwrapped.model, unwrapped.data, fingers, FINGER_TIPS, above=FINGER_ABOVE
    )
    d, body = unwrapped.data, physics.pen_body_id
    inertia = unwrapped.model.body_inertia[body]
    held, accel, exact, euler = [], [], [], []
    for _ in range(STEPS):
        _, _, terminated, truncated, info = env.step(np.zeros(10, dtype=np.float32))
        recorder.sample(unwrapped)
        contacts = physics.finger_contacts()
        held.append(info["is_success"] and contacts.active.all() and not physics.other_contacts())
        # Contact frames: orthonormal, the normal pointing from the contact into the pen.
        np.testing.assert_allclose(
            contacts.frames @ contacts.frames.transpose(0, 2, 1),
            np.eye(3)[None].repeat(2, 0),
            atol=1e-12,
        )
        inward = physics.pen_com() - contacts.points
        assert (np.einsum("ij,ij->i", contacts.frames[:, 0], inward)[contacts.active] > 0).all()
        accel.append(physics.pen_acceleration())
        exact.append(contacts.moment.sum(axis=0))
        # Euler in the world frame: I alpha + omega x I omega, I rotated by ximat; a free
        # joint's angular velocity and acceleration are in the body frame.
        rot, irot = d.xmat[body].reshape(3, 3), d.ximat[body].reshape(3, 3)
        world_inertia = (irot * inertia) @ irot.T
        dof = physics.pen_dof_adr
        alpha, omega = rot @ d.qacc[dof + 3 : dof + 6], rot @ d.qvel[dof + 3 : dof + 6]
        euler.append(mj_to_paper(world_inertia @ alpha + np.cross(omega, world_inertia @ omega)))
        if terminated or truncated:
            break
    env.close()
    model = recorder.model()
    mask = np.array(held)
    assert mask.sum() > 150
    f_ext = model.f_ext[1:][mask]
    force = f_ext[:, :3] + PEN_MASS * GRAVITY - PEN_MASS * np.array(accel)[mask]
    assert np.linalg.norm(force, axis=1).max() < 1e-3  # [N]
    exact_moment = np.array(exact)[mask]
    assert np.linalg.norm(exact_moment - np.array(euler)[mask], axis=1).max() < 1e-4  # [N m]
    assert np.linalg.norm(f_ext[:, 3:] - exact_moment, axis=1).max() < 1e-9  # [N m]


def _pinch(points: np.ndarray, normals: np.ndarray, active: tuple[bool, bool]) -> FingerContacts:
    """Two contacts with frames [n, t1 = x-ish, t2] (paper frame)."""
    frames = []
    for n in normals:
        t1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
        t1 /= np.linalg.norm(t1)
        frames.append(np.stack([n, t1, np.cross(t1, n)]))
    return FingerContacts(
        active=np.array(active),
        points=points,
        frames=np.array(frames),
        force=np.zeros((2, 3)),
        moment=np.zeros((2, 3)),
        count=np.array(active, dtype=np.int64),
        torsion=np.zeros(2),
        friction=np.array([[0.25, 0.03], [0.25, 0.03]]),
    )


@pytest.mark.parametrize("angle", [math.pi, 0.75 * math.pi, 0.6 * math.pi])
def test_squeeze_null_vector_of_a_pinch(angle: float) -> None:
    """Two contacts on a 1 cm pen, ``angle`` apart around it, squeezing along their chord."""
    r = 0.01
    thumb = np.array([0.0, -r, 0.0])  # below the pen, pushing up
    index = r * np.array([0.0, -math.cos(angle), math.sin(angle)])
    points = np.stack([index, thumb])
    contacts = _pinch(points, -points / r, (True, True))
    W = wrench_matrix(points, contacts.frames)
    assert np.linalg.matrix_rank(W) == 5  # no moment about the chord: G (eq. 8) does not exist
    N = squeeze_null_vector(W, contacts)
    assert N is not None
    np.testing.assert_allclose(W @ N, 0.0, atol=1e-15)
    assert np.linalg.norm(N) == pytest.approx(1.0)
    # A squeeze of s = 2 N by each finger along the chord: f_int = sqrt(2) s.
    chord = (thumb - index) / np.linalg.norm(thumb - index)
    s = 2.0
    c = np.concatenate([contacts.frames[0] @ (s * chord), contacts.frames[1] @ (-s * chord)])
    assert N @ c == pytest.approx(math.sqrt(2.0) * s)
    assert N @ -c == pytest.approx(-math.sqrt(2.0) * s)  # pulling apart is negative
    # One finger off the pen, or both at one point (rank 3): no squeeze.
    one = _pinch(points, contacts.frames[:, 0], (True, False))
    W_one = wrench_matrix(points, one.frames)
    W_one[:, 3:] = 0.0
    assert squeeze_null_vector(W_one, one) is None
    same = _pinch(np.stack([thumb, thumb]), contacts.frames[:, 0], (True, True))
    assert squeeze_null_vector(wrench_matrix(same.points, same.frames), same) is None


def test_glove_session_source() -> None:
    assert glove_session_source("teleop", "g7") == "glove:g7"
    assert glove_session_source("random", "g7") == "random+glove:g7"
    assert glove_session_source("glove:g1", "g7") == "glove:g1"


def test_skill_model_validates_the_pinch_width() -> None:
    S = 3
    base = {
        "time": np.arange(S, dtype=float),
        "touching": np.ones((S, 2), dtype=bool),
        "sliding": np.zeros((S, 2), dtype=bool),
        **{k: np.zeros((S, 3)) for k in ("pen_position", "pen_rpy", "pen_velocity", "pen_omega")},
        "c": np.zeros((S, 6)),
        "c_h": np.zeros((S, 6)),
        "f_ext": np.zeros((S, 6)),
        "f_int": np.zeros((S, 1)),
    }
    SkillModel(**base).validate()
    with pytest.raises(ValueError, match=r"model.f_int must have shape \(3, 1\)"):
        SkillModel(**{**base, "f_int": np.zeros((S, 0))}).validate()
    three = {**base, "touching": np.ones((S, 3), bool), "sliding": np.zeros((S, 3), bool)}
    with pytest.raises(ValueError, match="n >= 7"):
        SkillModel(**three).validate()


def _run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="ias-gym")
    add_skills_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    code: int = args.run(args)
    return code


def test_cli_records_and_shows_a_glove_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    db = str(tmp_path / "cli.db")
    assert _run(["skills", "record", "--env", ENV_ID, "--policy", "teleop", "--episodes", "1",
                 "--db", db, "--seed", "4", "--no-progress"]) == 0  # fmt: skip
    assert f"stored 1 skills (ids 1) in {db}" in capsys.readouterr().out

    assert _run(["skills", "list", "--db", db, "--json"]) == 0
    listed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert len(listed) == 1 and listed[0]["task"] == ENV_ID and listed[0]["length"] == STEPS
    assert listed[0]["source"] == f"glove:{DEFAULT_GLOVE_ID}" and listed[0]["is_success"]

    assert _run(["skills", "show", "--db", db, "--id", "1"]) == 0
    text = capsys.readouterr().out
    assert "person p1" in text and "finger 2: touching" in text
    assert "grip transform defined (rank W = 6)" in text and "f_int[2] [" in text
    assert _run(["skills", "show", "--db", db, "--id", "1", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert shown["person_id"] == "p1" and shown["seed"] == 4
    assert len(shown["model"]["fingers"]) == 2 and len(shown["model"]["f_int_range"]) == 2
    # The normal force is every 4th column of a soft finger's c: the pads press the pen.
    for finger in shown["model"]["fingers"]:
        low, high = finger["normal_force_range"]
        assert low == 0.0 and 0.3 < high < 5.0  # [N]: off the pen at reset, then pressing
    assert shown["model"]["max_pen_excursion"] >= 0.03

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    assert _run(["skills", "export", "--db", db, "--dataset-id", "ias/glove-v0"]) == 0
    assert str(tmp_path / "datasets" / "ias" / "glove-v0") in capsys.readouterr().out

    # The glove env has no expert; teleop needs a glove; the person is the env's.
    with pytest.raises(InputError, match=f"{ENV_ID} has no expert"):
        _run(["skills", "record", "--env", ENV_ID, "--db", db, "--no-progress"])
    with pytest.raises(InputError, match="needs a glove env"):
        _run(["skills", "record", "--env", "IAS-PenRotate-v0", "--policy", "teleop",
              "--db", db, "--no-progress"])  # fmt: skip
    with pytest.raises(InputError, match="belong to 'p1'"):
        _run(["skills", "record", "--env", ENV_ID, "--policy", "teleop", "--person", "p2",
              "--env-kwargs", '{"person_id": "p1"}', "--db", db, "--no-progress"])  # fmt: skip
    with SkillDB(db) as database:
        assert len(database) == 1  # the refused runs stored nothing


def test_a_recorded_skill_carries_its_own_timeline(tmp_path: Path) -> None:
    """A glove skill session stores its phase per sample: the record alone gives where the
    skill's motion starts and ends (the env's own times), and transfer starts there; a record
    without phases (an older one) says it has none."""
    import dataclasses

    from ias_gym.skills.glove_session import PHASE_INFO, motion_window
    from ias_gym.skills.transfer import skill_start_index

    path = tmp_path / "timeline.db"
    record_skills_spec(
        ENV_ID, "teleop", 1, path, seed=0, progress=False, env_kwargs={"skill": "tilt_left"}
    )
    env = gym.make(ENV_ID, skill="tilt_left")
    start, end = env.unwrapped.skill_start, env.unwrapped.skill_end
    env.close()
    with SkillDB(path, readonly=True) as db:
        skill = db.get(db.ids()[0])
    window = motion_window(skill)
    assert window is not None and start is not None and end is not None
    assert window[0] == pytest.approx(start, abs=0.0101) and window[1] == pytest.approx(
        end, abs=0.0101
    )
    assert skill.model.time[skill_start_index(skill)] == pytest.approx(window[0])
    infos = {k: v for k, v in skill.demonstration.infos.items() if k != PHASE_INFO}
    older = dataclasses.replace(
        skill, demonstration=dataclasses.replace(skill.demonstration, infos=infos)
    )
    assert motion_window(older) is None


def test_a_recorded_session_describes_its_person_and_intended_motion(tmp_path: Path) -> None:
    """A session stores its person's parameters and the object motion they meant (the
    reward's target), and a record stored without them (an older one) gets exactly those from
    ``skills migrate``, which never replaces what a record has and leaves other records."""
    import dataclasses
    import sqlite3

    from ias_gym.cli import main
    from ias_gym.glove.skills import SkillStyle, person_parameters, skill_object_target
    from ias_gym.skills.glove_session import TARGET_INFO, object_target

    path = tmp_path / "described.db"
    record_skills_spec(
        ENV_ID, "teleop", 1, path, seed=0, progress=False, env_kwargs={"skill": "seesaw_slow"}
    )
    record_skills_spec("IAS-PenSlide-v0", "expert", 1, path, seed=0, progress=False)
    with SkillDB(path) as db:
        glove_id, pen_id = db.ids()
        skill = db.get(glove_id)
        assert db.get(pen_id).person_params is None  # no person demonstrated it
        assert skill.person_params == pytest.approx(person_parameters("p1"))
        target = object_target(skill)
        assert target is not None
        style = SkillStyle.sample("p1")
        expected = np.array(
            [skill_object_target("seesaw_slow", t, style) for t in skill.model.time]
        )
        np.testing.assert_allclose(np.stack(target, axis=1), expected, atol=1e-12)
        assert np.ptp(target[1]) > 0.05  # a see-saw's target tilts
        # an older record: the same session without them
        infos = {k: v for k, v in skill.demonstration.infos.items() if k not in TARGET_INFO}
        older = dataclasses.replace(
            skill,
            demonstration=dataclasses.replace(skill.demonstration, infos=infos),
            person_params=None,
            id=None,
        )
        older_id = db.add(older)
    assert main(["skills", "migrate", "--db", str(path)]) == 0
    with SkillDB(path, readonly=True) as db:
        migrated = db.get(older_id)
        assert migrated.person_params == skill.person_params
        for key in TARGET_INFO:
            np.testing.assert_allclose(
                migrated.demonstration.infos[key], skill.demonstration.infos[key], atol=1e-12
            )
        assert db.get(pen_id).person_params is None
    with sqlite3.connect(path) as conn:  # two arrays added, nothing else
        (count,) = conn.execute(
            "SELECT count(*) FROM arrays WHERE skill_id = ?", (older_id,)
        ).fetchone()
        (first,) = conn.execute(
            "SELECT count(*) FROM arrays WHERE skill_id = ?", (glove_id,)
        ).fetchone()
    assert count == first
    with SkillDB(path) as db:
        with pytest.raises(SkillDBError, match="has the infos"):
            db.describe(older_id, infos={TARGET_INFO[0]: np.zeros(skill.length + 1)})
        with pytest.raises(SkillDBError, match="has its person_params"):
            db.describe(older_id, person_params={"hand_scale": 1.0})
        with pytest.raises(ValueError, match="finite"):
            db.describe(pen_id, person_params={"hand_scale": float("nan")})


def test_a_session_without_phases_is_left_and_consumers_say_so(tmp_path: Path) -> None:
    """A glove record without phases cannot be described from today's person generator: the
    migration leaves it and says why; the recognition metrics refuse it naming the fix."""
    import dataclasses

    from ias_gym.assist.metrics import labelled_session
    from ias_gym.skills.glove_session import PHASE_INFO, describe_session

    path = tmp_path / "old.db"
    record_skills_spec(
        ENV_ID, "teleop", 1, path, seed=0, progress=False, env_kwargs={"skill": "tilt_left"}
    )
    with SkillDB(path, readonly=True) as db:
        skill = db.get(db.ids()[0])
    infos = {k: v for k, v in skill.demonstration.infos.items() if k != PHASE_INFO}
    older = dataclasses.replace(
        skill, demonstration=dataclasses.replace(skill.demonstration, infos=infos)
    )
    add, person, why = describe_session(older)
    assert not add and person is None and "record it anew" in why
    with pytest.raises(InputError, match=r"does not store its phases.*skills record"):
        labelled_session(older)
