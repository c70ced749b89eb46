"""The assistant as a policy on observations (ias_gym.assist.policy): it reads only the
observation and the skill database, completes a stopped skill only when it knows the skill,
leaves a session alone without skill knowledge, and refuses bad parameter files."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401
from ias_gym.assist.pad_contact import PINCH_JOINTS_OF
from ias_gym.assist.policy import (
    AssistParams,
    frame_from_observation,
    make_assistant,
)
from ias_gym.assist.skill_motions import load_motions
from ias_gym.assist.stream import frames_from_env
from ias_gym.errors import InputError
from ias_gym.glove.hand import joint_index
from ias_gym.perturbed_starts import perturbed_starts
from ias_gym.sim.pen import R_PAPER_TO_MJ, matrix_to_rpy, mj_to_paper

PRON = joint_index("wrist_pronation")
FLEX = joint_index("wrist_flexion")


#: A stop detector that latches (the development value): these tests are about what the
#: assistant does once a stop is latched, not about the fitted threshold's rates, which
#: train/fit_assistant.py reports. The tremor canceller, which touches every joint a
#: little, is off in them (tests/test_assist_tremor.py tests it), and so is the pad keeping,
#: which closes a finger whenever its pad is off the pen while the other's is on
#: (tests/test_assist_pads.py).
LATCHING = AssistParams(
    stop_window_s=0.1, stop_ratio=0.3, pad_close_rate=AssistParams.load().pad_close_rate
)


def _sessions(
    recogniser: str, impairment: str, skill: str = "tilt_left", pads: bool = False
) -> list[tuple]:
    """(operator's targets, commanded targets, assistant, pen heights [m]) of the session
    from reset seed 0 and from its nearby starts
    (:func:`~ias_gym.perturbed_starts.perturbed_starts`), the assistant fed nothing but
    observations (no env object)."""
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", skill=skill, impairment=impairment)
    u = env.unwrapped
    layout = dict(u.observation_layout)
    scale = u.config.action_scale
    out = []
    for options in list(perturbed_starts(env, 0)):
        assistant = make_assistant(
            recogniser=recogniser,
            params=LATCHING,
            layout=layout,
            action_scale=scale,
            tremor=False,
            pads=pads,
        )
        obs, _ = env.reset(seed=0, options=options)
        operator, commanded, heights = [], [], []
        done = False
        while not done:
            action = assistant.act(obs.copy())
            theta = obs[layout["upcoming_theta"]]
            operator.append(theta.copy())
            commanded.append(theta + scale * action)
            obs, _, terminated, truncated, _ = env.step(action)
            heights.append(float(obs[layout["pen_position"]][2]))
            done = terminated or truncated
        out.append((np.array(operator), np.array(commanded), assistant, np.array(heights)))
    env.close()
    return out


def test_a_frame_from_the_observation_is_the_envs_own() -> None:
    """The observation's pen pose (the body's world pose from the step's kinematics) turned
    into the paper frame as the simulator's own pen pose is (``matrix_to_rpy`` of the
    rotation in the paper frame), and the recogniser's frame of the env agrees on the
    features it reads (pitch and yaw; roll, the pen's spin about its axis, is no feature)."""
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", skill="tilt_left")
    u = env.unwrapped
    obs, _ = env.reset(seed=0)
    for k in range(250):
        obs, *_ = env.step(np.zeros(10))
        if k % 50 == 49:
            mine = frame_from_observation(obs, u.observation_layout, np.zeros(10))
            body = u._pen_body
            rot = R_PAPER_TO_MJ.T @ u.data.xmat[body].reshape(3, 3) @ R_PAPER_TO_MJ
            np.testing.assert_allclose(mine.pen_rpy, matrix_to_rpy(rot), atol=1e-12)
            moved = mj_to_paper(u.data.xpos[body] - u._pen_start)
            np.testing.assert_allclose(mine.pen_position, moved, atol=1e-12)
            theirs = frames_from_env(env)
            np.testing.assert_allclose(mine.pen_rpy[1:], theirs.pen_rpy[1:], atol=1e-3)
            assert mine.time_s == pytest.approx(theirs.time_s)
    env.close()


def test_the_library_motions_are_the_skills_own() -> None:
    motions = load_motions()
    assert "lift_hold" not in motions  # it moves nothing beyond the hold
    for name in ("tilt_left", "tilt_right", "seesaw_slow"):
        assert PRON in motions[name].joints
    assert np.min(motions["tilt_left"].delta) < -0.1 < 0.1 < np.max(motions["tilt_right"].delta)


def test_a_stopped_tilt_is_completed_with_skill_knowledge_and_not_without() -> None:
    for op, cmd, assistant, height in _sessions("phase", "stops:at=0.4"):
        assert "tilt_left" in assistant.stopped
        # one skill is completed, on its principal joint, though others latched too, and
        # the pen held at the skill's height by the wrist's flexion
        assert assistant.completing == "tilt_left"
        others = ~np.isin(np.arange(cmd.shape[1]), [PRON, FLEX])
        np.testing.assert_allclose(cmd[:, others], op[:, others], atol=1e-9)
        turned_op = op[0, PRON] - op[-1, PRON]
        turned_cmd = cmd[0, PRON] - cmd[-1, PRON]
        # the hand is turned on, the way the skill turns, well beyond the operator's stop
        assert turned_cmd > turned_op + 0.04
        # the hold starts once the motion is done and brings the pen nearer the height
        # where the demonstrations leave it
        goal = assistant.motions["tilt_left"].goal_height
        held = np.flatnonzero(np.abs(cmd[:, FLEX] - op[:, FLEX]) > 1e-9)
        assert held.size and held[0] > len(cmd) // 2
        assert abs(height[-1] - goal) < abs(height[held[0]] - goal)
    for op_n, cmd_n, blind, _ in _sessions("none", "stops:at=0.4"):
        assert not blind.posterior().get("tilt_left")
        np.testing.assert_allclose(cmd_n, op_n, atol=1e-9)


def test_an_unimpaired_hold_is_left_alone() -> None:
    for op, cmd, _, _ in _sessions("phase", "none", skill="lift_hold"):
        np.testing.assert_allclose(cmd, op, atol=1e-9)
    # with the pad keeping (at the fitted rate): only the fingers, only closing, and no more
    # than a few steps' worth, where the pads meet a little later than the library's did
    fingers = [j for joints in PINCH_JOINTS_OF.values() for j in joints]
    for op, cmd, assistant, _ in _sessions("phase", "none", skill="lift_hold", pads=True):
        rest = np.delete(np.arange(cmd.shape[1]), fingers)
        np.testing.assert_allclose(cmd[:, rest], op[:, rest], atol=1e-9)
        assert np.all(cmd[:, fingers] - op[:, fingers] >= -1e-9)
        step = assistant.params.pad_close_rate * assistant.dt
        assert np.max(cmd[:, fingers] - op[:, fingers]) <= 3 * step + 1e-9


def test_the_hold_raises_a_low_pen_and_turns_it_to_the_operators_tilt_within_bounds() -> None:
    assistant = make_assistant(recogniser="phase", params=LATCHING, tremor=False)
    fit = assistant._fits["tilt_left"]
    motion = fit.motion
    assert 0.02 < motion.goal_height < 0.06 and motion.rise_per_flexion < 0
    # tilt_left raises the pen's +x end, by supination (negative pronation)
    assert motion.tilt_per_amplitude > 0.05 and motion.tilt_per_pronation < 0
    fit.fit = (1.2, 1.0, 2.0)  # an operator who means 1.2 times the typical tilt, from 2 s
    assistant._times, assistant._tilts = [1.9, 2.1, 2.5], [0.01, 0.01, 0.01]
    assistant._hold_pen(fit, motion.goal_height - 0.005)  # low, and not tilted yet
    assert assistant._hold[FLEX] < 0  # extension raises the pen
    assert assistant._hold[PRON] < 0  # supination tilts it on
    # at the operator's tilt and height there is nothing to hold
    assistant.reset()
    assistant._times, assistant._tilts = [1.9, 2.1, 2.5], [0.01, 0.01, 0.01]
    assistant._tilts[-1] = 0.01 + 1.2 * motion.tilt_per_amplitude
    assistant._hold_pen(fit, motion.goal_height)
    np.testing.assert_allclose(assistant._hold, 0.0, atol=1e-12)
    for _ in range(10_000):
        assistant._hold_pen(fit, motion.goal_height - 0.005)
    assert assistant._hold[FLEX] == pytest.approx(-assistant.scale)  # no more than an action's
    assistant.reset()
    assert not assistant._hold.any() and not assistant._tilts


def test_it_runs_on_an_observation_without_upcoming_targets() -> None:
    env = gym.make("IAS-GloveGrasp-v0", person_id="p1", skill="tilt_left")
    layout = dict(env.unwrapped.observation_layout)
    assert "upcoming_theta" not in layout
    assistant = make_assistant(recogniser="phase", layout=layout)
    obs, _ = env.reset(seed=0)
    for _ in range(50):
        action = assistant.act(obs)
        assert action.shape == (10,) and np.all(np.abs(action) <= 1.0)
        obs, *_ = env.step(action.astype(np.float32))
    env.close()


def test_parameter_files_are_checked(tmp_path: Path) -> None:
    good = tmp_path / "params.json"
    AssistParams(stop_ratio=0.3).save(good)
    assert AssistParams.load(good).stop_ratio == 0.3
    off = tmp_path / "off.json"
    off.write_text(json.dumps({"tremor_floor_rad": 0}))
    assert AssistParams.load(off).tremor_floor_rad == 0  # 0 switches detection off
    with pytest.raises(FileExistsError):
        AssistParams().save(good)
    for text, match in (
        ("{", "unreadable"),
        (json.dumps({"stop_ratio": -1}), "not valid"),
        (json.dumps({"tremor_trend_degree": 2.5}), "not valid"),
        (json.dumps({"tremor_trend_degree": 0}), "not valid"),
        (json.dumps({"tremor_trend_degree": True}), "not valid"),
        (json.dumps({"tremor_floor_rad": -0.01}), "not valid"),
        (json.dumps({"stop_ratio": 0}), "not valid"),
        (json.dumps({"exec": 1}), "keys"),
    ):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(InputError, match=match):
            AssistParams.load(bad)
    with pytest.raises(InputError, match="not exist"):
        AssistParams.load(tmp_path / "missing.json")
    with pytest.raises(InputError, match="recogniser"):
        make_assistant(recogniser="psychic")


def test_the_detection_ablation_notches_every_operator() -> None:
    params = AssistParams(tremor_floor_rad=0.01)
    with_it = make_assistant(recogniser="none", params=params)
    without = make_assistant(recogniser="none", params=params, detection=False)
    assert with_it.tremor is not None and with_it.tremor.floor_rad == 0.01
    assert without.tremor is not None and without.tremor.floor_rad == 0.0
    assert without.params.tremor_floor_rad == 0.0 and params.tremor_floor_rad == 0.01
