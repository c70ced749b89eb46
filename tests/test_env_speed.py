"""The control period ``dt`` of every env, and what a pen-task reset costs: the grasp's
inverse kinematics does the old work in fewer MuJoCo passes and gives the same pose bit for
bit (so the reset distribution, and every result built on it, is unchanged)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.envs.pen_hand_env import NOMINAL_CONTACT_X
from ias_gym.registration import ENV_SPECS
from ias_gym.sim import grasp_pose
from ias_gym.sim.grasp_pose import place_grasp
from ias_gym.sim.pen_hand import PenHandPhysics, paper_to_mj, rpy_to_matrix

PEN_IDS = ("IAS-PenSlide-v0", "IAS-PenRotate-v0")


@pytest.mark.parametrize("env_id", sorted(ENV_SPECS))
@pytest.mark.parametrize("control_dt", [0.01, 0.02])
def test_every_env_has_its_control_period_as_dt(env_id: str, control_dt: float) -> None:
    env = gym.make(env_id, control_dt=control_dt)
    u: Any = env.unwrapped
    assert u.dt == pytest.approx(control_dt, abs=1e-12)
    assert u.dt == pytest.approx(u.model.opt.timestep * u.frame_skip, abs=1e-12)
    # one step advances the simulation by dt
    env.reset(seed=0)
    t0 = u.data.time
    env.step(env.action_space.sample() * 0)
    assert u.data.time - t0 == pytest.approx(u.dt, abs=1e-9)
    env.close()


def test_the_hardware_env_has_dt_too() -> None:
    from ias_gym.hardware.env import GloveHardwareEnv

    assert isinstance(GloveHardwareEnv.dt, property)  # inherited from IAS-GloveGrasp-v0


def _reference_place_grasp(
    physics: PenHandPhysics,
    pen_position: np.ndarray,
    pen_rpy: np.ndarray,
    contact_x: np.ndarray,
    penetration: float = 3e-4,
    iterations: int = 30,
    tolerance: float = 1e-7,
) -> float:
    """place_grasp as it was: one Gauss-Newton solve per finger, MuJoCo's Jacobians,
    a full kinematics pass per iteration."""
    m, d = physics.model, physics.data
    qa = physics.pen_qpos_adr
    rot = rpy_to_matrix(pen_rpy)
    centre = np.asarray(pen_position, dtype=float)
    d.qpos[qa : qa + 3] = physics.origin_mj + paper_to_mj(centre)
    rot_mj = paper_to_mj(paper_to_mj(rot).T).T
    mujoco.mju_mat2Quat(d.qpos[qa + 3 : qa + 7], rot_mj.reshape(-1))
    d.qvel[:] = 0.0
    tip_radius = m.geom_size[physics.tip_geom_ids, 0]
    pen_radius = m.geom_size[physics.pen_geom_id, 0]
    offset = np.array([1.0, -1.0, -1.0, 1.0]) * (pen_radius + tip_radius - penetration)
    local = np.stack([np.asarray(contact_x, dtype=float), offset, np.zeros(4)], axis=1)
    targets = physics.origin_mj + paper_to_mj(centre + local @ rot.T)
    qadr, dadr = physics.hand_qpos_ids, physics.hand_dof_ids
    lo, hi = m.jnt_range[m.dof_jntid[dadr]].T
    jac = np.zeros((3, m.nv))
    err = np.inf
    for _ in range(iterations):
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        residual = targets - d.site_xpos[physics.tip_site_ids]
        err = float(np.abs(residual).max())
        if err < tolerance:
            break
        for i, site in enumerate(physics.tip_site_ids):
            mujoco.mj_jacSite(m, d, jac, None, int(site))
            cols = dadr[3 * i : 3 * i + 3]
            J = jac[:, cols]
            step = np.linalg.solve(J.T @ J + 1e-8 * np.eye(3), J.T @ residual[i])
            q = qadr[3 * i : 3 * i + 3]
            d.qpos[q] = np.clip(d.qpos[q] + step, lo[3 * i : 3 * i + 3], hi[3 * i : 3 * i + 3])
    mujoco.mj_forward(m, d)
    return err


def _poses(n: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(7)
    return [
        (
            rng.uniform(-1e-3, 1e-3, 3),
            np.array([0.0, 0.0, rng.uniform(-0.08, 0.08)]),  # PenRotate's tilts
            NOMINAL_CONTACT_X + rng.uniform(-1e-3, 1e-3, 4),
        )
        for _ in range(n)
    ]


@pytest.mark.parametrize("from_keyframe", [True, False])
def test_the_grasp_is_the_one_of_the_reference_inverse_kinematics_bit_for_bit(
    from_keyframe: bool,
) -> None:
    """From the keyframe (the cached first iteration) and from another posture (none)."""
    fast, ref = PenHandPhysics.from_assets(), PenHandPhysics.from_assets()
    key = fast.model.key("grasp").id
    for pose in _poses(25):
        for p in (fast, ref):
            mujoco.mj_resetDataKeyframe(p.model, p.data, key)
            if not from_keyframe:
                p.data.qpos[p.hand_qpos_ids] += 0.01
        err = place_grasp(fast, *pose)
        assert err == _reference_place_grasp(ref, *pose)
        np.testing.assert_array_equal(fast.data.qpos, ref.data.qpos)
        assert err < 1e-7


class _Counting:
    """Stands in for the mujoco module inside grasp_pose, counting some calls."""

    COUNTED = ("mj_kinematics", "mj_comPos", "mj_jacSite", "mj_forward")

    def __init__(self) -> None:
        self.calls = dict.fromkeys(self.COUNTED, 0)

    def __getattr__(self, name: str) -> Any:
        target = getattr(mujoco, name)
        if name not in self.COUNTED:
            return target

        def counted(*args: Any, **kwargs: Any) -> Any:
            self.calls[name] += 1
            return target(*args, **kwargs)

        return counted


@pytest.mark.parametrize("env_id", PEN_IDS)
def test_a_reset_runs_fewer_mujoco_passes(env_id: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The work of one reset's inverse kinematics with s Gauss-Newton steps: the first
    iteration's kinematics and Jacobians at the keyframe are cached, so s kinematics passes,
    s - 1 Jacobian passes (mj_comPos + one mj_jacSite per finger), one mj_forward. Before:
    s + 1 of each pass (mj_comPos even where no step followed) and s Jacobian passes."""
    env = gym.make(env_id)
    env.reset(seed=0)
    k = env.unwrapped.physics.n_fingers  # type: ignore[attr-defined]
    counting = _Counting()
    monkeypatch.setattr(grasp_pose, "mujoco", counting)
    for seed in range(10):
        counting.calls = dict.fromkeys(_Counting.COUNTED, 0)
        env.reset(seed=seed)
        calls = counting.calls
        steps = calls["mj_kinematics"]
        assert 1 <= steps <= 3, calls  # Gauss-Newton: 1 mm to 1e-7 m in a few steps
        assert calls == {
            "mj_kinematics": steps,
            "mj_comPos": steps - 1,
            "mj_jacSite": k * (steps - 1),
            "mj_forward": 1,
        }
    env.close()
