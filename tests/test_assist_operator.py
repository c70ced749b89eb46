"""IAS-GloveAssist-v0's operator: the person in the loop by default, impairments inside it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.envs.glove_assist import SWITCH_BLEND, SwitchingOperator
from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.glove.closed_loop import ClosedLoopOperator, inner_plan
from ias_gym.glove.device import WorldView
from ias_gym.glove.hand import PersonParams, joint_index
from ias_gym.glove.impairments import StopsOperator, TremorOperator, WeakGripOperator
from ias_gym.glove.operator import skill_operator
from ias_gym.glove.skills import SkillOperator
from tests.closed_loop import perturbed_starts, typical_person

ZERO = np.zeros(10, dtype=np.float32)


def _plan(skill: str = "tilt_left") -> SkillOperator:
    person = PersonParams.sample(typical_person())
    plan = skill_operator(person, 0.01, skill)
    assert isinstance(plan, SkillOperator)
    return plan


def test_the_env_runs_the_operator_its_config_names() -> None:
    env = gym.make("IAS-GloveAssist-v0", person_id=typical_person(), skill="tilt_left")
    env.reset(seed=0)
    assert isinstance(env.unwrapped.operator, ClosedLoopOperator)  # type: ignore[attr-defined]
    env.close()
    env = gym.make(
        "IAS-GloveAssist-v0", person_id=typical_person(), skill="tilt_left", operator="script"
    )
    env.reset(seed=0)
    assert env.unwrapped.operator is None  # type: ignore[attr-defined]
    env.close()


def test_the_person_judges_an_impaired_plan_by_the_skill_inside_it() -> None:
    plan = _plan()
    wrapped = TremorOperator(WeakGripOperator(StopsOperator(plan, 0.4), 0.1), 0.05, 10.0, "p", 0)
    assert inner_plan(wrapped) is plan
    op = ClosedLoopOperator(wrapped, plan.base.person, object_weight=0.1, friction=0.5)
    assert op.intent is plan and op.skill == "tilt_left"
    stop = StopsOperator(plan, 0.4)
    assert op.holds_still_from == pytest.approx(stop.stop_time)
    with pytest.raises(TypeError, match="wraps no"):
        inner_plan(lambda t: np.zeros(10))  # type: ignore[arg-type]
    # a motion done to its end is no stop: the person corrects as ever
    assert StopsOperator(plan, 1.0).holds_still_from == math.inf


def test_a_stopped_person_no_longer_corrects_by_sight() -> None:
    """Shown a pen far under its goal, the stopped person's correction by sight does not change
    from their stop on; the same person doing the whole skill corrects after its end."""
    plan = _plan()
    moves = {}
    for name, executed in (("stopped", StopsOperator(plan, 0.4)), ("whole", plan)):
        op = ClosedLoopOperator(executed, plan.base.person, object_weight=0.1, friction=0.5)
        start = op.start
        t_end = plan.duration - start + 0.5  # episode time after the skill's motion
        level = np.array([1.0, 0.0, 0.0, 0.0])
        low = np.array([0.0, 0.0, 0.01])  # 30 mm under the lift's goal
        wf = joint_index("wrist_flexion")
        targets = []
        for k in range(int(t_end / 0.01) + 150):
            t = 0.01 * k
            op.see(WorldView(t, low if t > 0.5 else np.zeros(3), level))
            targets.append(op(t)[wf] - executed(t + start)[wf])
        at_stop = round((StopsOperator(plan, 0.4).stop_time - start) / 0.01)
        moves[name] = abs(targets[-1] - targets[at_stop])
    assert moves["stopped"] < 1e-9 and moves["whole"] > 0.05


def test_a_switch_is_a_skill_plan_blending_the_two() -> None:
    a, b = _plan("tilt_left"), _plan("lift_place")
    switch = SwitchingOperator(a, b, a.skill_start + 0.3)
    assert switch.skill == "lift_place" and switch.duration == max(a.duration, b.duration)
    before, after = a.skill_start + 0.1, a.skill_start + 0.3 + SWITCH_BLEND + 0.1
    np.testing.assert_allclose(switch(before), a(before))
    np.testing.assert_allclose(switch.offsets(after), b.offsets(after))


def _pen_path(env: gym.Env, options: dict | None = None) -> np.ndarray:
    obs, _ = env.reset(seed=0, options=options)
    part = env.unwrapped.observation_layout["pen_position"]  # type: ignore[attr-defined]
    path, done = [], False
    while not done:
        obs, _, terminated, truncated, _ = env.step(ZERO)
        path.append(obs[part])
        done = terminated or truncated
    return np.array(path)


@pytest.mark.closed_loop
def test_the_unimpaired_session_is_the_glove_worlds() -> None:
    """Read one sample ahead, the same person in the loop moves the pen as in
    IAS-GloveGrasp-v0, from nearby starts (the assistant's world is the glove world)."""
    person = typical_person()
    assist = gym.make("IAS-GloveAssist-v0", person_id=person, skill="lift_place")
    grasp = GloveGraspEnv(person_id=person, skill="lift_place")
    for options in perturbed_starts(grasp, seed=0, n=2):
        gap = np.abs(_pen_path(assist, options) - _pen_path(grasp, options)).max()
        assert gap < 1e-3, options is None
    assist.close()
    grasp.close()


@pytest.mark.closed_loop
def test_a_lag_sets_the_person_in_the_loop_swinging() -> None:
    """A 0.3 s lag the person does not know of: the lifted pen swings for the person in the
    loop, not for the open script (the impairment reaches the operator through the env)."""
    person = typical_person()
    swing = {}
    for operator in ("closed_loop", "script"):
        for spec in ("none", "lag:s=0.3"):
            env = gym.make(
                "IAS-GloveAssist-v0",
                person_id=person,
                skill="lift_hold",
                impairment=spec,
                operator=operator,
            )
            swing[operator, spec] = float(np.std(_pen_path(env)[250:, 2]))
            env.close()
    assert swing["closed_loop", "lag:s=0.3"] > 3.0 * swing["closed_loop", "none"] + 0.002
    assert swing["script", "lag:s=0.3"] < 2.0 * swing["script", "none"] + 0.001
