"""The closed-loop simulated person: perceives with delays, corrects, fails like a person."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.errors import InputError
from ias_gym.glove.closed_loop import ClosedLoopOperator, _Delayed, pen_tilt
from ias_gym.glove.device import SimulatedGlove, WorldView
from ias_gym.glove.hand import INDEX_JOINTS, PersonParams
from ias_gym.glove.impairments import LaggedGlove
from ias_gym.glove.operator import FromPreShape, skill_operator
from ias_gym.glove.skills import LIFT_GOAL, SKILLS, SkillStyle, skill_object_target
from tests.closed_loop import perturbed_starts, typical_person

ZERO = np.zeros(10, dtype=np.float32)


def _quat_about_y(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0])


def test_the_pen_tilt_is_positive_when_its_plus_x_end_rises() -> None:
    # a rotation about world y by -a lifts the +x end by a
    assert pen_tilt(_quat_about_y(-0.1)) == pytest.approx(0.1)
    assert pen_tilt(_quat_about_y(0.2)) == pytest.approx(-0.2)
    assert pen_tilt(np.array([1.0, 0.0, 0.0, 0.0])) == 0.0


def test_a_perception_arrives_only_after_its_delay() -> None:
    seen: _Delayed[str] = _Delayed(0.07)
    seen.push(0.0, "a")
    seen.push(0.05, "b")
    assert seen.at(0.06) is None
    assert seen.at(0.08) == "a"
    assert seen.at(0.12) == "b"  # the latest old enough


def _operator(person_id: str, skill: str = "lift_hold") -> ClosedLoopOperator:
    person = PersonParams.sample(person_id)
    plan = skill_operator(person, 0.01, skill)
    return ClosedLoopOperator(plan, person, object_weight=1.0, friction=0.25)


def test_a_person_who_sees_the_pen_fall_gives_up_and_holds_still() -> None:
    op = _operator(typical_person())
    fallen = WorldView(0.0, np.array([0.0, 0.0, -0.03]), np.array([1.0, 0.0, 0.0, 0.0]))
    for k in range(300):
        t = 0.01 * k
        theta = op(t)
        if k == 110:  # after the hold: the pen is seen below its start
            op.see(WorldView(t, fallen.pen_position, fallen.pen_quat))
        if op.failure:
            frozen = theta
            break
    assert op.failure == "dropped the pen"
    np.testing.assert_array_equal(op(3.0), frozen)
    np.testing.assert_array_equal(op(3.5), frozen)


def test_the_person_aims_for_their_margin_above_the_slip_force() -> None:
    person = typical_person()
    op = _operator(person)
    margin = SkillStyle.sample(person).grip_margin
    assert op.grip_goal == pytest.approx((1 + margin) * 1.0 / (2 * 0.25))
    with pytest.raises(ValueError):
        ClosedLoopOperator(op.plan, op.person, object_weight=0.0, friction=0.25)


@pytest.mark.parametrize("felt_share", [0.5, 3.0])
def test_the_person_loosens_toward_their_goal_but_never_squeezes_deeper_than_planned(
    felt_share: float,
) -> None:
    """Felt below the goal, the pinch stays the plan's (a deeper index flexion pushes the
    pen off the thumb); felt far above it, it loosens, down to half the plan's."""
    op = _operator(typical_person())
    dt = 0.01
    t0 = op.timings.close - op.start + 0.05  # episode time just after the close
    plan0 = np.asarray(op.plan(t0 + op.start))
    tau = np.array([0.05, 0.03, 0.01, -0.04, -0.02])
    tau *= felt_share * op.grip_goal / op.felt_force(tau, plan0)
    index = list(INDEX_JOINTS[:2])  # index MCP and PIP: what the squeeze moves
    deeper = []
    for k in range(200):
        t = t0 + k * dt
        op.feel(t, tau)
        theta = op(t)
        plan = np.asarray(op.plan(t + op.start))
        deeper.append(float(np.dot(theta[index] - plan[index], op._squeeze_dir[index])))
    assert max(deeper) <= 1e-12
    if felt_share > 1:
        assert min(deeper) < -1e-4  # loosened
        assert op._squeeze == pytest.approx(0.5 * op._planned_force)
    else:
        assert op._squeeze == op._planned_force


def test_the_env_takes_a_known_operator_only() -> None:
    with pytest.raises(InputError, match="closed_loop"):
        gym.make("IAS-GloveGrasp-v0", operator="puppet")
    env = GloveGraspEnv(person_id=typical_person(), skill="lift_hold", operator="script")
    env.reset(seed=0)
    assert env.operator is None and isinstance(env.glove, SimulatedGlove)
    assert isinstance(env.glove.operator, FromPreShape)  # the open-loop plan alone
    env.close()


def _heights(env: GloveGraspEnv, options: dict | None = None) -> tuple[np.ndarray, list[dict]]:
    env.reset(seed=0, options=options)
    heights, infos, done = [], [], False
    while not done:
        _, _, terminated, truncated, info = env.step(ZERO)
        heights.append(info["pen_height"])
        infos.append(info)
        done = terminated or truncated
    return np.array(heights), infos


@pytest.mark.closed_loop
def test_the_person_holds_the_pen_at_their_goal_and_feels_its_pinch() -> None:
    """From nearby starts a typical person's lifted pen ends within 2 mm of the lift goal
    (the open-loop plan alone ends 3.4 mm off on average, development persons), and the
    pinch force they infer from the force display is the contacts' within a third."""
    env = GloveGraspEnv(person_id=typical_person(), skill="lift_hold")
    for options in perturbed_starts(env, seed=0, n=2):
        heights, infos = _heights(env, options)
        assert abs(heights[-1] - LIFT_GOAL) < 0.002, options is None
        op = env.operator
        assert op is not None and infos[-1]["operator_failure"] == ""
        glove = env.glove
        assert isinstance(glove, SimulatedGlove) and glove.last_theta is not None
        felt = op.felt_force(env._feedback, glove.last_theta)
        assert felt == pytest.approx(infos[-1]["pinch_force"], rel=0.35)
    env.close()


@pytest.mark.closed_loop
def test_a_glove_lag_the_person_does_not_know_of_makes_them_overshoot() -> None:
    """Their corrections are tuned to their own delay: 0.3 s more sets the lifted pen
    swinging (the open-loop plan alone does not notice a lag)."""
    swing = {}
    for operator in ("closed_loop", "script"):
        for lag in (0.0, 0.3):
            env = GloveGraspEnv(person_id=typical_person(), skill="lift_hold", operator=operator)
            if lag:
                inner = env.glove_factory
                env.glove_factory = lambda seed, inner=inner: LaggedGlove(inner(seed), 30)
            heights, _ = _heights(env)
            swing[operator, lag] = float(np.std(heights[250:]))
            env.close()
    assert swing["closed_loop", 0.3] > 3.0 * swing["closed_loop", 0.0] + 0.002
    assert swing["script", 0.3] < 2.0 * swing["script", 0.0] + 0.001


@pytest.mark.parametrize("skill", SKILLS)
def test_a_skills_object_target_starts_at_rest_and_lifts_to_the_goal(skill: str) -> None:
    assert skill_object_target(skill, 0.0) == (0.0, 0.0)
    height, _ = skill_object_target(skill, 1.7)  # the lift's end, before any skill moves
    assert height == pytest.approx(LIFT_GOAL)
    end_height, end_tilt = skill_object_target(skill, 4.0)
    if skill == "lift_place":
        assert end_height == pytest.approx(0.0, abs=1e-9)
    elif skill.startswith("tilt"):
        assert (end_tilt > 0.1) == (skill == "tilt_left") and abs(end_tilt) > 0.1
    else:
        assert end_height == pytest.approx(LIFT_GOAL) and abs(end_tilt) < 1e-9


@pytest.mark.closed_loop
def test_skills_return_differently_and_doing_a_skill_earns_more_than_holding_still() -> None:
    """The reward follows the skill: a tilt and a place earn more done than with the pen held
    still (the open-loop plan, so that only the performed skill differs)."""
    person = typical_person()
    returns = {}
    for skill in ("tilt_right", "lift_place"):
        for performed in (skill, "lift_hold"):
            env = GloveGraspEnv(person_id=person, skill=skill, operator="script")
            radius = float(env.model.geom_size[env.model.geom("pen").id, 0])
            plan = skill_operator(env.person, radius, performed)
            env.glove_factory = lambda seed, plan=plan, env=env: SimulatedGlove(
                env.person, FromPreShape(plan), seed
            )
            env.reset(seed=0)
            total, done = 0.0, False
            while not done:
                _, reward, terminated, truncated, info = env.step(ZERO)
                assert reward == pytest.approx(
                    sum(info[f"reward_{k}"] for k in ("lift", "track", "pinch", "effort"))
                )
                total += float(reward)
                done = terminated or truncated
            returns[skill, performed] = total
            env.close()
    for skill in ("tilt_right", "lift_place"):
        assert returns[skill, skill] > returns[skill, "lift_hold"] + 30.0
    assert returns["tilt_right", "tilt_right"] != returns["lift_place", "lift_place"]
