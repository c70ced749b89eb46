"""The retargeting baseline: the hands' URDF, dex-retargeting on it, the policy, the CLI.

The URDF export is checked against MuJoCo itself (its tips where MuJoCo's sites are, at
random joint angles, for every registered hand), then through dex-retargeting's own robot
with the coupled joints as mimic joints; the policy is run briefly on a human lift from
nearby starts; the missing package and the command line are checked as a user meets them.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from closed_loop import perturbed_starts

from ias_gym.errors import InputError
from ias_gym.sim.hands import hand_names
from ias_gym.sim.pen_hand import PenHandPhysics
from ias_gym.sim.urdf_export import pen_hand_urdf

pin = pytest.importorskip("pinocchio", reason="the retarget extra is not installed")


def physics_of(hand: str) -> PenHandPhysics:
    try:
        return PenHandPhysics.from_assets(hand=hand)
    except InputError as exc:  # the Shadow or LEAP hand's package is missing
        pytest.skip(str(exc))


def random_hand_angles(physics: PenHandPhysics, rng: np.random.Generator) -> dict[str, float]:
    """Angles within their ranges for every joint of the URDF (followers independently)."""
    m = physics.model
    angles = {}
    for j in range(m.njnt):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-np.pi, np.pi)
            angles[name] = float(rng.uniform(lo, hi))
    return angles


def mujoco_tips(physics: PenHandPhysics, angles: dict[str, float]) -> np.ndarray:
    m, d = physics.model, mujoco.MjData(physics.model)
    d.qpos[:] = physics.data.qpos
    for name, value in angles.items():
        d.qpos[m.jnt_qposadr[m.joint(name).id]] = value
    mujoco.mj_kinematics(m, d)
    return d.site_xpos[physics.tip_site_ids].copy()


@pytest.mark.parametrize("hand", hand_names())
def test_the_urdf_puts_the_tips_where_mujoco_does(hand: str, tmp_path: Path) -> None:
    physics = physics_of(hand)
    urdf = pen_hand_urdf(physics, hand)
    model = pin.buildModelFromUrdf(str(urdf.write(tmp_path / f"{hand}.urdf")))
    data = model.createData()
    # every driven joint and every coupled one, nothing else moves
    assert set(model.names[1:]) == set(urdf.joints) | {f for f, *_ in urdf.mimic}
    assert len(urdf.tips) == physics.n_fingers
    rng = np.random.default_rng(7)
    for _ in range(25):
        angles = random_hand_angles(physics, rng)
        q = np.zeros(model.nq)
        for name in model.names[1:]:
            q[model.joints[model.getJointId(name)].idx_q] = angles[name]
        pin.framesForwardKinematics(model, data, q)
        tips = np.array([data.oMf[model.getFrameId(t)].translation for t in urdf.tips])
        assert np.max(np.abs(tips - mujoco_tips(physics, angles))) < 1e-9  # [m]


@pytest.mark.parametrize("hand", hand_names())
def test_dex_retargeting_reads_the_coupled_joints_and_solves_reachable_tips(hand: str) -> None:
    from ias_gym.baselines.retarget import build_retargeting

    physics = physics_of(hand)
    urdf = pen_hand_urdf(physics, hand)
    retargeting = build_retargeting(urdf)
    optimizer = retargeting.optimizer
    assert list(optimizer.target_joint_names) == list(urdf.joints)  # the driven ones only
    assert (optimizer.adaptor is not None) == bool(physics.coupled)
    # the grasp keyframe's tips, from 0.05 rad away: solved back to within 0.1 mm
    names = list(retargeting.joint_names)
    start = np.asarray(retargeting.get_qpos(), dtype=float)
    start[[names.index(j) for j in urdf.joints]] = physics.hand_qpos() + 0.05
    retargeting.set_qpos(start)
    solved = np.asarray(retargeting.retarget(physics.data.site_xpos[physics.tip_site_ids]))
    angles = {n: float(solved[names.index(n)]) for n in names}
    for follower, leader, ratio, offset in urdf.mimic:  # set from the leader, as MuJoCo's
        assert angles[follower] == pytest.approx(ratio * angles[leader] + offset, abs=1e-6)
    reached = mujoco_tips(physics, angles)
    assert (
        np.max(np.linalg.norm(reached - physics.data.site_xpos[physics.tip_site_ids], axis=1))
        < 1e-4
    )


def shipped_lift_hold(hand: str, duration: float):  # type: ignore[no-untyped-def]
    from ias_gym.skills.db import SkillDB
    from ias_gym.skills.transfer import shipped_skill_db, transfer_reference

    with SkillDB(shipped_skill_db(), readonly=True) as db:
        summary = next(s for s in db.list_skills(success=True) if s.name == "lift_hold")
        skill = db.get(summary.id)
    return transfer_reference(skill, hand, duration=duration)


@pytest.mark.closed_loop
def test_the_policy_holds_a_nominal_lift_from_nearby_starts() -> None:
    from ias_gym.baselines.retarget import RetargetPolicy
    from ias_gym.envs.pen_skill_env import PenSkillEnv

    env = PenSkillEnv(references=[shipped_lift_hold("ias4f", 0.3)], hand="ias4f", duration=0.3)
    for options in perturbed_starts(env, seed=0, n=1):
        policy = RetargetPolicy(env)
        obs, info = env.reset(seed=0, options={**(options or {}), "skill": 0})
        done, steps = False, 0
        while not done:
            action, _ = policy.predict(obs)
            assert action.shape == env.action_space.shape and np.all(np.abs(action) <= 1.0)
            obs, _, terminated, truncated, info = env.step(action)
            done, steps = terminated or truncated, steps + 1
        assert steps == 30 and not info["dropped"] and env.held()
        assert policy.failures == 0 and policy.residual < 1e-4  # [m]: the keypoints reached


def test_a_missing_dex_retargeting_is_one_input_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from ias_gym.baselines import retarget
    from ias_gym.envs.pen_skill_env import PenSkillEnv

    for name in [n for n in sys.modules if n.split(".")[0] == "dex_retargeting"]:
        monkeypatch.setitem(sys.modules, name, None)  # as if not installed
    monkeypatch.setitem(sys.modules, "dex_retargeting", None)
    monkeypatch.setattr(retarget, "_BUILT", {})
    env = PenSkillEnv(references=[shipped_lift_hold("ias4f", 0.3)], duration=0.3)
    with pytest.raises(InputError) as error:
        retarget.RetargetPolicy(env)
    message = str(error.value)
    assert "pip install 'ias-gym[retarget]'" in message and "\n" not in message


def cli(*args: str, hide_package: bool = False) -> subprocess.CompletedProcess[str]:
    hide = "sys.modules['dex_retargeting'] = None; " if hide_package else ""
    code = f"import sys; {hide}from ias_gym.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, "skills", "transfer", *args],
        capture_output=True,
        text=True,
        check=False,
    )


@pytest.fixture(scope="module")
def skill_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from transfer_fixtures import synthetic_skill

    from ias_gym.skills.db import SkillDB

    path = tmp_path_factory.mktemp("retarget") / "skills.db"
    with SkillDB(path) as db:
        db.add(synthetic_skill(lift=0.02, tilt=0.15, duration=1.0))
    return path


def test_the_cli_runs_the_retargeting_baseline(skill_db: Path) -> None:
    out = cli(
        "--db", str(skill_db), "--id", "1", "--method", "retarget", "--duration", "0.4", "--json"
    )
    assert out.returncode == 0, out.stderr
    row = json.loads(out.stdout)  # one line: nothing else printed on stdout
    assert row["method"] == "retarget" and row["hand"] == "ias4f"
    assert row["success"] == (row["held"] and row["tracked"] and row["margin_kept"])
    assert 0 < row["held_s"] <= 0.4 + 1e-9


def test_the_cli_names_the_extra_when_dex_retargeting_is_missing(skill_db: Path) -> None:
    out = cli("--db", str(skill_db), "--id", "1", "--method", "retarget", hide_package=True)
    assert out.returncode == 2 and out.stdout == ""
    assert len(out.stderr.strip().splitlines()) == 1 and "Traceback" not in out.stderr
    assert "pip install 'ias-gym[retarget]'" in out.stderr
