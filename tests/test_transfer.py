"""Skill transfer: the grasp margin, references from stored skills, their execution, the CLI.

The margin is tested against invariants first (a two-contact grasp whose least squeeze is
known in closed form, homogeneity in c_h, m = 1 on a cone's boundary, the torsion bound)
and against a brute-force scan; then a synthetic skill (a SkillModel built here, whose
trajectory and margin are known) is transferred and executed in closed loop.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from closed_loop import perturbed_starts
from hypothesis import given, settings
from hypothesis import strategies as st
from transfer_fixtures import (
    DT,
    MU,
    antipodal_pinch,
    random_contacts,
    synthetic_skill,
    transfer_cli,
)

from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.baselines.kinematic import KinematicPolicy
from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.grasp.grasp_margin import (
    grasp_margin,
    least_squeeze,
    margin_series,
    scale_to_margin,
)
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import (
    SkillTransferError,
    implied_wrench,
    transfer_reference,
)
from ias_gym.skills.transfer_run import run_transfer, transfer_gains
from ias_gym.skills.workspace import HandWorkspace


# ---------------------------------------------------------------------------- the margin
@pytest.mark.parametrize("weight, squeeze", [(1.0, 4.0), (1.0, 2.0), (0.3, 5.0), (2.0, 1.0)])
def test_margin_of_an_antipodal_pinch_has_its_closed_form(weight: float, squeeze: float) -> None:
    # Each contact carries weight / 2 by friction: the least squeeze is weight / (2 mu),
    # so m = squeeze * 2 mu / weight.
    c_p, c_h = antipodal_pinch(weight, squeeze)
    assert least_squeeze(c_p, c_h, MU) == pytest.approx(weight / (2 * MU * squeeze), rel=1e-12)
    assert grasp_margin(c_p, c_h, MU) == pytest.approx(squeeze * 2 * MU / weight, rel=1e-12)


def test_margin_is_one_exactly_on_the_cone_boundary() -> None:
    c_p, c_h = antipodal_pinch(1.0, 1.0)
    c_h = c_h / (2 * MU)  # now |c_t| = mu c_n at both contacts
    c = c_p + c_h
    assert np.hypot(c[1], c[2]) == pytest.approx(MU * c[0], rel=1e-14)
    assert grasp_margin(c_p, c_h, MU) == pytest.approx(1.0, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.1, 3.0),
    st.floats(0.1, 10.0),
    st.floats(0.05, 20.0),
    st.integers(0, 2**32 - 1),
)
def test_scaling_c_h_by_k_scales_the_margin_by_k(
    weight: float, squeeze: float, k: float, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    c_p, c_h = antipodal_pinch(weight, squeeze)
    # tangential parts inside the cone (|t| <= 0.14 n < mu n): some scale always holds
    t = rng.uniform(-0.1, 0.1, 4) * squeeze
    c_h = c_h + np.array([0, t[0], t[1], 0, t[2], t[3]])
    m = grasp_margin(c_p, c_h, MU)
    assert math.isfinite(m) and m > 0
    assert grasp_margin(c_p, k * c_h, MU) == pytest.approx(k * m, rel=1e-9)
    # and scale_to_margin inverts it: the hand's own c_h scaled to any demonstrated margin
    target = float(rng.uniform(0.5, 5.0))
    assert grasp_margin(c_p, scale_to_margin(c_p, c_h, target, MU), MU) == pytest.approx(
        target, rel=1e-9
    )


def inside(c: np.ndarray, mu: float, per: int, mu_t: float = 0.0, tol: float = 1e-9) -> np.ndarray:
    """Whether each row of ``c`` (..., n) lies in every contact's cone."""
    rows = c.reshape(*c.shape[:-1], -1, per)
    ok = rows[..., 0] >= -tol
    ok &= np.hypot(rows[..., 1], rows[..., 2]) <= mu * rows[..., 0] + tol
    if per == 4:
        ok &= np.abs(rows[..., 3]) <= mu_t * rows[..., 0] + tol
    return np.asarray(ok.all(axis=-1))


@pytest.mark.parametrize("per", [3, 4])
def test_least_squeeze_is_the_least_feasible_scale_found_by_a_scan(per: int) -> None:
    # Random particular parts (any signs, any directions) and squeezes that hold at some
    # scale or at none: s* must be feasible, anything a little smaller infeasible, and a
    # fine scan must agree, also that no scale holds where s* is inf.
    rng = np.random.default_rng(per)
    mu_t = 0.005
    grid = np.linspace(0.0, 20.0, 20001)
    found = {"finite": 0, "inf": 0}
    for _ in range(300):
        c_p, c_h = random_contacts(rng, per)
        s = least_squeeze(c_p, c_h, MU, mu_t, per)
        feasible = inside(c_p + grid[:, None] * c_h, MU, per, mu_t)
        if math.isinf(s):
            found["inf"] += 1
            assert not feasible.any()
            continue
        found["finite"] += 1
        assert inside(c_p + s * c_h, MU, per, mu_t, tol=1e-7)
        if s > 1e-6:
            assert not inside(c_p + s * (1 - 1e-6) * c_h, MU, per, mu_t, tol=0.0)
        if s < grid[-1]:
            assert s == pytest.approx(grid[np.argmax(feasible)], abs=grid[1] + 1e-9)
    assert found["finite"] > 50 and found["inf"] > 5, found


def test_torsion_bounds_a_soft_finger_squeeze() -> None:
    # One soft finger's torsion needs mu_t c_n >= |tau|: s* = |tau| / (mu_t n_h).
    c_p = np.array([0.0, 0.0, 0.0, 0.002, 0.0, 0.0, 0.0, -0.002])
    c_h = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    assert least_squeeze(c_p, c_h, MU, 0.005) == pytest.approx(0.4, rel=1e-12)
    assert least_squeeze(c_p, c_h, MU, 0.0) == math.inf  # no torsional friction: no hold


def test_margin_series_is_nan_where_a_contact_is_missing() -> None:
    c_p, c_h = antipodal_pinch(1.0, 4.0)
    touching = np.array([[True, True], [True, False], [True, True]])
    m = margin_series(np.tile(c_p, (3, 1)), np.tile(c_h, (3, 1)), touching, MU)
    assert np.isnan(m[1]) and m[0] == pytest.approx(2.0) and m[2] == pytest.approx(2.0)


# ---------------------------------------------------------------------------- a synthetic skill


def test_reference_starts_at_the_grasp_and_is_scaled_into_the_workspace() -> None:
    skill = synthetic_skill(lift=0.02, tilt=0.15)
    ws = HandWorkspace(reach=0.005, tilt=0.25)
    ref = transfer_reference(skill, workspace=ws, control_dt=DT)
    # from the grasp's own start (0.3 s into the recording), as a displacement
    assert np.allclose(ref.position[0], 0.0, atol=1e-6)
    assert np.allclose(ref.axis[0], [1.0, 0.0, 0.0], atol=1e-6)
    assert ref.length == round((2.5 - 0.3) / DT) + 1
    # translation scaled so that the largest displacement is the reach; angles kept
    largest = math.hypot(0.02, 0.004)
    assert ref.scale == pytest.approx(0.005 / largest, rel=1e-9)
    assert np.max(np.linalg.norm(ref.position, axis=1)) == pytest.approx(0.005, rel=2e-3)
    assert ref.scale_rotation == 1.0
    tilt = np.arctan2(ref.axis[:, 1], np.hypot(ref.axis[:, 0], ref.axis[:, 2]))
    assert tilt.max() == pytest.approx(0.15, abs=2e-3)
    # the derivatives are those of the resampled motion (smoothstep: v = lift * 6u(1-u))
    t = np.arange(ref.length) * DT
    u = np.clip(t / 1.0, 0, 1)
    v = ref.scale * 0.02 * 6 * u * (1 - u)
    assert np.max(np.abs(ref.velocity[5:-5, 1] - v[5:-5])) < 0.02 * v.max()
    # the margin of the pinch: 2 mu squeeze / weight
    assert np.allclose(ref.margin, 2 * MU * 4.0 / 1.0)


def test_a_larger_rotation_is_scaled_to_the_hands_largest_tilt() -> None:
    ref = transfer_reference(
        synthetic_skill(tilt=0.5), workspace=HandWorkspace(0.005, 0.25), control_dt=DT
    )
    assert ref.scale_rotation == pytest.approx(0.5, rel=1e-3)
    tilt = np.arctan2(ref.axis[:, 1], np.hypot(ref.axis[:, 0], ref.axis[:, 2]))
    assert tilt.max() == pytest.approx(0.25, abs=3e-3)


def test_the_reference_does_not_depend_on_the_demonstrations_heading() -> None:
    ws = HandWorkspace(0.005, 0.25)
    a = transfer_reference(synthetic_skill(heading=0.0), workspace=ws, control_dt=DT)
    b = transfer_reference(synthetic_skill(heading=0.7), workspace=ws, control_dt=DT)
    assert np.allclose(a.position, b.position, atol=1e-9)
    assert np.allclose(a.axis, b.axis, atol=1e-9)


def test_implied_wrench_holds_the_weight_at_rest() -> None:
    ref = transfer_reference(synthetic_skill(), workspace=HandWorkspace(0.005, 0.25))
    mass = 1.0 / 9.81
    w = implied_wrench(ref, mass, np.diag([1e-6, 1e-4, 1e-4]))
    # at rest after the motion: the weight (eq. 18's sign: the fingers push up)
    assert np.allclose(w[-1], [0.0, 1.0, 0.0, 0.0, 0.0, 0.0], atol=1e-6)
    # while lifting, the force is m (a - g): more than the weight while accelerating up
    k = int(np.argmax(ref.acceleration[:, 1]))
    assert w[k, 1] == pytest.approx(1.0 + mass * ref.acceleration[k, 1], rel=1e-12)


def test_a_skill_without_contacts_cannot_be_transferred() -> None:
    with pytest.raises(SkillTransferError, match="no sample where every finger touches"):
        transfer_reference(synthetic_skill(touching=False))


# ---------------------------------------------------------------------------- execution
def reference_for_test() -> SkillReference:
    return transfer_reference(
        synthetic_skill(lift=0.02, tilt=0.15), workspace=HandWorkspace(0.005, 0.2), duration=2.0
    )


@pytest.mark.closed_loop
def test_the_expert_tracks_a_transferred_skill_from_perturbed_starts() -> None:
    ref = reference_for_test()
    env = PenSkillEnv(references=[ref], duration=2.0)
    for options in perturbed_starts(env, seed=3, n=3):
        env.reset(seed=3, options={**(options or {}), "skill": 0})
        expert = ExpertPolicy(env)
        obs, info = env.reset(seed=3, options={**(options or {}), "skill": 0})
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(expert.predict(obs)[0])
            done = terminated or truncated
        assert info["is_success"], info
        assert info["rms_position_error"] < 1e-3  # [m]
        assert math.degrees(info["rms_rotation_error"]) < 1.5
        # the hand squeezes with the demonstrated margin (2.0) within 20 %
        assert 0 <= env.margin_error() < 0.2 and info["margin_error"] == env.margin_error()


def mean_margin(margin: float, floor: float = 1.0) -> float:
    ref = reference_for_test()
    ref = SkillReference(**{**ref.__dict__, "margin": np.full(ref.length, margin)})
    gains = dataclasses.replace(transfer_gains("ias4f"), margin_floor=floor)
    run, _ = run_transfer(ref, method="gt", duration=1.0, gains=gains)
    held = run.time > 0.2
    return float(np.nanmean(run.margin[held]))


def test_the_expert_squeezes_to_the_skills_margin() -> None:
    # The margin hook: twice the margin asked gives twice the margin measured (without
    # it the expert holds its own least-force grip whatever the skill asks).
    low, high = mean_margin(2.0), mean_margin(4.0)
    assert low == pytest.approx(2.0, rel=0.2)
    assert high / low == pytest.approx(2.0, rel=0.15)


def test_the_margin_floor_lifts_a_smaller_margin_to_it_and_leaves_a_larger_one() -> None:
    # The robot's own safety margin (ControllerGains.margin_floor): a demonstrated margin
    # below it is held at the floor, one above it as demonstrated.
    floored, kept = mean_margin(1.2, floor=2.0), mean_margin(3.0, floor=2.0)
    assert floored == pytest.approx(2.0, rel=0.2)
    assert kept == pytest.approx(3.0, rel=0.2)


@pytest.mark.parametrize("hand", ["ias4f", "ias3f"])
def test_the_kinematic_baseline_runs_and_holds_a_slow_skill(hand: str) -> None:
    # (on the three-finger hand only with the squeeze balanced between the sides)
    ref = reference_for_test()
    env = PenSkillEnv(references=[ref], duration=2.0, hand=hand)
    policy = KinematicPolicy(env)
    obs, info = env.reset(seed=0)
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        done = terminated or truncated
    assert not info["dropped"]
    assert info["rms_position_error"] < 5e-3  # it sags under the weight, but holds
    assert math.isfinite(env.margin_error())


# ---------------------------------------------------------------------------- the CLI


@pytest.fixture(scope="module")
def skill_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("transfer") / "skills.db"
    with SkillDB(path) as db:
        db.add(synthetic_skill(lift=0.02, tilt=0.15, duration=1.5))
        db.add(synthetic_skill(touching=False, duration=1.0))
        db.add(synthetic_skill(lift=0.02, tilt=0.15, duration=1.5, success=False))
    return path


def test_cli_prints_one_json_object_per_hand_with_units(skill_db: Path) -> None:
    out = transfer_cli(
        "--db", str(skill_db), "--id", "1", "--hand", "all", "--json", "--duration", "1.2"
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    rows = [json.loads(line) for line in lines]
    listing = transfer_cli("--list-hands")
    assert len(rows) == len(listing.stdout.strip().splitlines())
    keys = {"hand", "method", "success", "rot_rms_deg", "pos_rms_mm", "margin_err_rel", "scale"}
    for row in rows:
        assert keys <= set(row)
        assert row["method"] == "gt" and row["success"] is True
        # units: mm and degrees (a value in m or rad would be 1000 or 57 times smaller)
        assert 0.01 < row["pos_rms_mm"] < 3.0
        assert 0.01 < row["rot_rms_deg"] < 3.0
        assert 0 < row["scale"] <= 1


@pytest.mark.parametrize(
    "args, message",
    [
        (["--id", "9"], "no skill with id 9"),
        (["--id", "1", "--hand", "robonaut"], "unknown --hand 'robonaut'"),
        (["--id", "2"], "no sample where every finger touches"),
        (["--id", "1", "--method", "joint"], "unknown --method"),
        (["--id", "3"], "skill 3 in"),
    ],
)
def test_cli_errors_are_one_line_with_exit_code_2(
    skill_db: Path, args: list[str], message: str
) -> None:
    out = transfer_cli("--db", str(skill_db), *args)
    assert out.returncode == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert "Traceback" not in out.stderr


def test_cli_runs_under_a_disturbance_class_and_names_the_terms() -> None:
    out = transfer_cli("--id", "1", "--hand", "ias4f", "--disturbance", "mass_x1.3", "--json")
    assert out.returncode == 0, out.stderr
    row = json.loads(out.stdout)
    assert row["disturbance"] == "mass_x1.3"
    assert {"held", "tracked", "margin_kept"} <= set(row)
    assert row["success"] == (row["held"] and row["tracked"] and row["margin_kept"])
    assert set(row["tolerance"]) == {"rot_rms_deg", "pos_rms_mm", "margin_err_rel"}


def test_cli_refuses_an_unknown_disturbance_in_one_line() -> None:
    out = transfer_cli("--id", "1", "--disturbance", "gravity_x2")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "unknown --disturbance 'gravity_x2'" in out.stderr and "friction_x0.7" in out.stderr


def test_a_failed_demonstration_is_refused_unless_allowed(skill_db: Path) -> None:
    """A demonstration whose own episode failed is not a skill to transfer by default."""
    refused = transfer_cli(
        "--db", str(skill_db), "--id", "3", "--hand", "ias3f", "--duration", "0.5"
    )
    assert refused.returncode == 2 and "--allow-failed" in refused.stderr
    allowed = transfer_cli(
        "--db",
        str(skill_db),
        "--id",
        "3",
        "--hand",
        "ias3f",
        "--duration",
        "0.5",
        "--allow-failed",
        "--json",
    )
    assert allowed.returncode == 0, allowed.stderr
    assert json.loads(allowed.stdout)["hand"] == "ias3f"


def test_cli_refuses_an_existing_video_before_any_work(skill_db: Path, tmp_path: Path) -> None:
    video = tmp_path / "v.mp4"
    video.write_bytes(b"keep")
    out = transfer_cli("--db", str(skill_db), "--id", "1", "--video", str(video))
    assert out.returncode == 2 and "exists" in out.stderr
    assert video.read_bytes() == b"keep"


# ---------------------------------------------------------------------------- Minari
def test_minari_export_of_robot_executions_of_human_skills(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    import minari

    from ias_gym.skills.minari_export import export_pen_skill_dataset, pen_skill_dataset_id

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    export_pen_skill_dataset(hand="ias3f", skill_ids=[2, 9], db_path=tmp_path / "runs.db")
    dataset = minari.load_dataset(pen_skill_dataset_id("ias3f"))
    assert dataset.total_episodes == 2  # each chosen skill once
    episodes = list(dataset.iterate_episodes())
    assert {int(e.infos["skill_id"][0]) for e in episodes} == {2, 9}
    for episode in episodes:
        assert episode.actions.shape[1] == 9  # the three-finger hand's joints
        assert episode.infos["contact_forces"].shape[1:] == (3, 3)
        assert episode.infos["internal_forces"].shape[1:] == (9,)
        # the expert holds: normal forces push, and it executed the skill successfully
        held = episode.infos["fingers_in_contact"][1:].all(axis=1)  # after the first step
        assert held.mean() > 0.95
        assert np.all(episode.infos["contact_forces"][1:][held][:, :, 0] > 0)
        assert bool(episode.infos["is_success"][-1])
    env = dataset.recover_environment()
    assert env.unwrapped.config.hand == "ias3f"
    assert [r.skill_id for r in env.unwrapped.references] == [2, 9]


def _export_cli(minari_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ias_gym.cli", "skills", "export-pen-skill", *args],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "MINARI_DATASETS_PATH": str(minari_path)},
    )


def test_the_pen_skill_datasets_cover_every_hand(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``skills export-pen-skill --hand all``: one dataset per registered hand, each with its
    hand's action size and a recoverable env on that hand."""
    pytest.importorskip("minari")
    import minari

    from ias_gym.sim.hands import HANDS
    from ias_gym.skills.minari_export import PEN_SKILL_DATASET_ID, pen_skill_dataset_id

    done = _export_cli(tmp_path, "--hand", "all", "--skill-ids", "2")
    assert done.returncode == 0, done.stderr
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    assert pen_skill_dataset_id("ias4f") == PEN_SKILL_DATASET_ID
    for name, spec in HANDS.items():
        dataset = minari.load_dataset(pen_skill_dataset_id(name))
        assert dataset.total_episodes == 1
        episode = next(iter(dataset.iterate_episodes()))
        assert episode.actions.shape[1] == spec.n_dofs
        assert dataset.recover_environment().unwrapped.config.hand == name


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--hand", "allegro"], "unknown hand 'allegro'"),
        (["--hand", "all", "--dataset-id", "ias/x/y-v0"], "--dataset-id is for one hand"),
        (["--hand", "ias3f", "--skill-ids", "2,x"], "--skill-ids takes comma-separated"),
        (["--hand", "ias3f", "--episodes-per-skill", "0"], "--episodes-per-skill must be >= 1"),
    ],
)
def test_a_bad_export_is_one_line_and_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    pytest.importorskip("minari")
    done = _export_cli(tmp_path, *args)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "ias").exists()


def test_an_existing_dataset_is_not_overwritten(tmp_path: Path) -> None:
    pytest.importorskip("minari")
    kept = tmp_path / "ias" / "pen-skill-leap" / "human-v0"
    kept.mkdir(parents=True)
    (kept / "mine").write_text("keep")
    done = _export_cli(tmp_path, "--hand", "leap", "--skill-ids", "2")
    assert done.returncode == 2 and "exists already" in done.stderr, done.stderr
    assert (kept / "mine").read_text() == "keep"


def test_the_shipped_human_skills_hold_with_a_margin_of_at_least_one() -> None:
    # A person who did not drop the pen held it inside the cones: with the pads' torsional
    # friction (0.03 m) the demonstrated margin is >= 1 (up to the pads' creep) nearly
    # everywhere (p1, p2: 92-100 % of the samples); with the pen's 0.005 m the torsion
    # would look out of its cone and the margin 0 for most of the tilting skills.
    from ias_gym.skills.transfer import demonstrated_margin, shipped_skill_db, skill_start_index

    with SkillDB(shipped_skill_db(), readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            m = demonstrated_margin(skill)[skill_start_index(skill) :]
            # (a finger that slips for a moment, |c_t| slightly above mu c_n, has m = 0)
            assert np.mean(m >= 0.95) > 0.85, (skill.name, skill.person_id)
            assert 1.0 < np.nanmedian(m) < 2.0


def test_cli_runs_a_shipped_skill_by_default() -> None:
    out = transfer_cli("--id", "2", "--hand", "ias3f", "--json", "--duration", "0.6")
    assert out.returncode == 0, out.stderr
    (row,) = [json.loads(line) for line in out.stdout.strip().splitlines()]
    assert (row["hand"], row["skill"], row["person"]) == ("ias3f", "seesaw_slow", "p1")
    assert row["held_s"] == pytest.approx(0.6)


@pytest.mark.closed_loop
def test_the_leap_thumb_on_top_holds_a_squeeze_its_sticking_joints_can_set() -> None:
    """A shipped lift_place held at the edge of slipping, on the LEAP hand (0.02 N m of dry
    friction per joint). The thumb on top keeps the pen from every nearby start with the
    friction floor alone (its squeeze one its sticking joints can set) and with the approach
    alone (it opens and closes on the pen again); without either (the weaker method) the
    thumb's few hundredths of a newton are below what its joints can set, it opens, and the
    pen is lost. The squeeze is the demonstrated one (no margin floor of the robot's own,
    which would hold the pen by itself)."""
    import dataclasses

    from ias_gym.baselines.gains import ControllerGains
    from ias_gym.skills.transfer import shipped_skill_db

    with SkillDB(shipped_skill_db(), readonly=True) as db:
        skill = next(
            s
            for s in (db.get(i) for i in db.ids())
            if s.name == "lift_place" and s.person_id == "p2"
        )
    # the lift held to 6 mm (a workspace of its own, not the hand's measured one, which
    # changes when it is measured again)
    ref = transfer_reference(skill, "leap", workspace=HandWorkspace(0.006, 0.075))
    env = PenSkillEnv(references=[ref], hand="leap")
    starts = list(perturbed_starts(env, seed=0, n=2))
    env.close()
    both = dataclasses.replace(ControllerGains(), margin_floor=1.0)
    assert both.friction_floor > 0 and both.approach_speed > 0
    floor = dataclasses.replace(both, approach_speed=0.0)
    approach = dataclasses.replace(both, friction_floor=0.0)
    neither = dataclasses.replace(floor, friction_floor=0.0)
    for options in starts:
        for gains in (floor, approach):
            held, _ = run_transfer(ref, "leap", "gt", gains=gains, reset_options=options)
            assert held.held and held.margin_kept, (gains, held.held_s, held.margin_err_rel)
    dropped = [
        not run_transfer(ref, "leap", "gt", gains=neither, reset_options=o)[0].held for o in starts
    ]
    assert any(dropped)


@pytest.mark.closed_loop
def test_the_integral_takes_out_the_steady_offset_of_a_scaled_lift() -> None:
    """A shipped lift_place on the four-finger hand, its lift scaled to about an eighth: the
    tips' lateral servo leaves the proportional law a steady offset of the pen from its
    reference, about as large as the scaled tolerance; the transfer's integral gain takes
    most of it out from every nearby start, and the run is tracked."""
    import dataclasses

    from ias_gym.skills.transfer import shipped_skill_db
    from ias_gym.skills.transfer_run import TransferRun, transfer_gains

    with SkillDB(shipped_skill_db(), readonly=True) as db:
        skill = next(s for s in (db.get(i) for i in db.ids()) if s.name == "lift_place")
    ref = transfer_reference(skill, "ias4f")
    env = PenSkillEnv(references=[ref], hand="ias4f")
    starts = list(perturbed_starts(env, seed=0, n=2))
    env.close()
    gains = transfer_gains("ias4f")
    assert gains.ki > 0
    proportional = dataclasses.replace(gains, ki=0.0)

    def offset(run: TransferRun) -> float:  # the mean offset over the last second [m]
        late = run.time >= run.time[-1] - 1.0
        error = run.position[late] - run.reference_position[late]
        return float(np.linalg.norm(error.mean(axis=0)))

    for options in starts:
        integral, _ = run_transfer(ref, "ias4f", "gt", gains=gains, reset_options=options)
        plain, _ = run_transfer(ref, "ias4f", "gt", gains=proportional, reset_options=options)
        assert integral.held and integral.tracked, integral.pos_rms_mm
        assert offset(integral) < 0.3 * offset(plain), (offset(integral), offset(plain))


def test_the_gain_fit_chooses_by_success_and_refuses_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """train/fit_gain.py end to end on two of the shipped skills' persons (tiny: the Shadow
    hand, the friction floor at two shares, two folds), and its refusals before any work."""
    from train_scripts import load_train_script

    from ias_gym.skills.transfer import shipped_skill_db

    main = load_train_script("fit_gain").main
    out = tmp_path / "fit.json"
    db = str(shipped_skill_db())
    base = ["--db", db, "--hands", "shadow", "--grid", "0,0.5", "--folds", "2", "--workers", "1"]
    base += ["--gain", "friction_floor"]
    assert main([*base, "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    cells = result["by_hand_disturbance_and_value"]["shadow"]["nominal"]
    counts = {share: cells[share]["successes"] for share in ("0.0", "0.5")}
    assert result["chosen_value"] == (0.5 if counts["0.5"] > counts["0.0"] else 0.0)
    assert result["persons"] == 2 and len(result["folds"]) == 2
    fresh = str(tmp_path / "new.json")
    for bad, what in (
        (["--out", fresh, "--hands", "nohand"], "--hands nohand"),
        (["--out", fresh, "--folds", "1"], "--folds 1"),
        (["--out", fresh, "--gain", "cone"], "--gain cone"),
        (["--out", fresh, "--disturbances", "wind"], "wind"),
        (["--out", fresh, "--grid", "0,x"], "x"),
        (["--out", fresh, "--db", str(tmp_path / "missing.db")], "missing.db"),
        (["--out", str(out)], str(out)),  # exists, no --overwrite
    ):
        capsys.readouterr()
        assert main([*base, *bad]) == 2
        assert what in capsys.readouterr().err
    assert not Path(fresh).exists()
