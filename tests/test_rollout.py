"""The rollout core (ias_gym.rollout): one episode, its trajectory, its hooks, bad policies."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from ias_gym.errors import IasGymError
from ias_gym.rollout import FrameRecorder, FunctionPolicy, RolloutError, Trajectory, rollout


class CountingEnv(gym.Env[np.ndarray, np.ndarray]):
    """A toy env: the observation is (step, last action's sum), the reward a function of
    both; it terminates after ``terminate_at`` steps (None: never) and truncates after
    ``limit``; ``render`` gives the step as a 1 x 1 image."""

    metadata = {"render_modes": ["rgb_array"]}  # noqa: RUF012

    def __init__(self, terminate_at: int | None = None, limit: int = 10) -> None:
        self.terminate_at, self.limit = terminate_at, limit
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.render_mode = "rgb_array"
        self.steps = 0
        self.resets: list[tuple[int | None, dict[str, Any] | None]] = []
        self.stepped: list[np.ndarray] = []

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.steps = 0
        self.resets.append((seed, options))
        self.offset = float(self.np_random.uniform())
        return np.array([0.0, self.offset]), {"is_success": False, "step": 0}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.stepped.append(action)
        self.steps += 1
        total = float(np.sum(action))
        reward = 0.1 * self.steps + total + self.offset
        terminated = self.terminate_at is not None and self.steps >= self.terminate_at
        truncated = self.steps >= self.limit
        info = {"is_success": self.steps % 2 == 0, "step": self.steps}
        return np.array([float(self.steps), total]), reward, terminated, truncated, info

    def render(self) -> np.ndarray:
        return np.full((1, 1, 3), self.steps, dtype=np.uint8)


class RecordingPolicy:
    """A stateful SB3-style policy: records each call; its state counts the calls."""

    def __init__(self, action: Any = (0.25, -0.5)) -> None:
        self.action = action
        self.calls: list[tuple[Any, Any, bool]] = []

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        self.calls.append((np.array(observation), state, episode_start))
        return np.array(self.action, dtype=np.float32), (0 if state is None else state + 1)


def test_a_trajectory_has_t_steps_and_t_plus_one_observations_and_infos() -> None:
    env = CountingEnv(limit=7)
    trajectory = rollout(env, RecordingPolicy(), seed=3)
    assert isinstance(trajectory, Trajectory)
    assert trajectory.length == 7 == len(env.stepped)
    assert trajectory.actions.shape == (7, 2) and trajectory.actions.dtype == np.float32
    assert trajectory.rewards.shape == (7,) and trajectory.rewards.dtype == np.float64
    assert trajectory.observations is not None and trajectory.observations.shape == (8, 2)
    assert trajectory.infos is not None and len(trajectory.infos) == 8
    assert [info["step"] for info in trajectory.infos] == list(range(8))
    np.testing.assert_array_equal(trajectory.observations[1:, 0], np.arange(1, 8))
    np.testing.assert_array_equal(trajectory.final_observation, trajectory.observations[-1])
    assert trajectory.final_info is trajectory.infos[-1]
    assert trajectory.truncated and not trajectory.terminated and trajectory.done
    assert list(trajectory.truncations) == [False] * 6 + [True]
    assert not trajectory.terminations.any()
    assert trajectory.seed == 3 and env.resets == [(3, None)]
    assert trajectory.is_success is False  # step 7 is odd


def test_the_return_is_the_sum_of_the_rewards_in_order() -> None:
    trajectory = rollout(CountingEnv(limit=9), RecordingPolicy(), seed=0)
    total = 0.0
    for reward in trajectory.rewards.tolist():
        total += reward
    assert trajectory.episode_return == total
    assert trajectory.episode_return == pytest.approx(float(np.sum(trajectory.rewards)))


def test_the_hooks_see_the_reset_and_every_step() -> None:
    env = CountingEnv(limit=5)
    resets: list[Any] = []
    steps: list[tuple[Any, ...]] = []
    trajectory = rollout(
        env,
        RecordingPolicy(),
        seed=1,
        on_reset=lambda e, obs, info: resets.append((e, obs.copy(), info)),
        on_step=lambda e, obs, action, reward, info: steps.append((e, obs, action, reward, info)),
    )
    assert trajectory.observations is not None and trajectory.infos is not None
    assert len(resets) == 1 and resets[0][0] is env
    np.testing.assert_array_equal(resets[0][1], trajectory.observations[0])
    assert len(steps) == trajectory.length == 5
    for t, (e, obs, action, reward, info) in enumerate(steps):
        assert e is env
        np.testing.assert_array_equal(obs, trajectory.observations[t + 1])
        np.testing.assert_array_equal(action, trajectory.actions[t])
        assert action is env.stepped[t]  # the hook gets the action the env was stepped with
        assert reward == trajectory.rewards[t] and isinstance(reward, float)
        assert info is trajectory.infos[t + 1]


def test_an_episode_that_terminates_early_stops_there() -> None:
    env = CountingEnv(terminate_at=3, limit=10)
    trajectory = rollout(env, RecordingPolicy(), seed=0)
    assert trajectory.length == 3 == len(env.stepped)
    assert trajectory.terminated and not trajectory.truncated
    assert list(trajectory.terminations) == [False, False, True]


def test_max_steps_cuts_the_episode_without_ending_it() -> None:
    env = CountingEnv(limit=10)
    trajectory = rollout(env, RecordingPolicy(), seed=0, max_steps=4)
    assert trajectory.length == 4 and not trajectory.done
    assert trajectory.observations is not None and len(trajectory.observations) == 5
    empty = rollout(env, RecordingPolicy(), seed=0, max_steps=0)
    assert empty.length == 0 and empty.actions.shape == (0, 2) and not empty.done
    assert empty.observations is not None and len(empty.observations) == 1
    assert empty.final_info == {"is_success": False, "step": 0}
    with pytest.raises(ValueError, match="max_steps"):
        rollout(env, RecordingPolicy(), seed=0, max_steps=-1)


def test_a_stateful_policy_gets_episode_start_first_and_its_own_state_after() -> None:
    policy = RecordingPolicy()
    trajectory = rollout(CountingEnv(limit=4), policy, seed=0)
    assert [start for _, _, start in policy.calls] == [True, False, False, False]
    assert [state for _, state, _ in policy.calls] == [None, 0, 1, 2]
    assert trajectory.observations is not None
    for (obs, _, _), expected in zip(policy.calls, trajectory.observations[:-1], strict=True):
        np.testing.assert_array_equal(obs, expected)  # each action from the latest observation
    rollout(CountingEnv(limit=2), policy, seed=0)  # a second episode starts afresh
    assert [(state, start) for _, state, start in policy.calls[4:]] == [(None, True), (0, False)]


def test_without_observations_and_infos_the_outcome_is_the_same() -> None:
    full = rollout(CountingEnv(limit=6), RecordingPolicy(), seed=2)
    lean = rollout(
        CountingEnv(limit=6), RecordingPolicy(), seed=2, keep_observations=False, keep_infos=False
    )
    assert lean.observations is None and lean.infos is None
    assert lean.episode_return == full.episode_return and lean.length == full.length
    np.testing.assert_array_equal(lean.final_observation, full.final_observation)
    assert lean.final_info == full.final_info


def test_reset_options_and_the_action_dtype_reach_the_env() -> None:
    env = CountingEnv(limit=2)
    options = {"qpos": [1.0]}
    trajectory = rollout(
        env, RecordingPolicy(), seed=5, reset_options=options, action_dtype=np.float64
    )
    assert env.resets == [(5, options)] and env.resets[0][1] is not options  # a copy
    assert trajectory.actions.dtype == np.float64
    assert all(a.dtype == np.float64 for a in env.stepped)


def test_the_observations_are_copies_of_what_the_env_returned() -> None:
    """An env that reuses its observation buffer still leaves one row per step."""

    class Reusing(CountingEnv):
        buffer = np.zeros(2)

        def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
            obs, *rest = super().step(action)
            self.buffer[:] = obs
            return (self.buffer, *rest)  # type: ignore[return-value]

    trajectory = rollout(Reusing(limit=3), RecordingPolicy(), seed=0)
    assert trajectory.observations is not None
    np.testing.assert_array_equal(trajectory.observations[1:, 0], [1.0, 2.0, 3.0])


def test_a_function_of_the_observation_is_a_policy_through_its_adapter() -> None:
    seen: list[np.ndarray] = []

    def act(obs: np.ndarray) -> list[float]:
        seen.append(obs)
        return [0.5, 0.5]

    trajectory = rollout(CountingEnv(limit=3), FunctionPolicy(act), seed=0)
    assert len(seen) == 3
    np.testing.assert_array_equal(trajectory.actions, np.full((3, 2), 0.5))


def test_a_policy_of_the_wrong_shape_fails_at_its_first_step_saying_what_was_expected() -> None:
    env = CountingEnv(limit=5)
    with pytest.raises(RolloutError, match=r"step 0: .* shape \(3,\), .* needs \(2,\)") as err:
        rollout(env, RecordingPolicy(action=(0.1, 0.2, 0.3)), seed=0)
    assert isinstance(err.value, IasGymError) and env.stepped == []


@pytest.mark.parametrize(
    ("policy", "match"),
    [
        (FunctionPolicy(lambda obs: "left"), "not numbers"),
        (FunctionPolicy(lambda obs: [0.1, [0.2]]), "not an array of numbers"),
        (FunctionPolicy(lambda obs: np.zeros((1, 2))), r"shape \(1, 2\)"),
    ],
)
def test_an_action_that_is_not_an_array_of_numbers_is_refused(policy: Any, match: str) -> None:
    env = CountingEnv()
    with pytest.raises(RolloutError, match=match):
        rollout(env, policy, seed=0)
    assert env.stepped == []


def test_predict_must_return_an_action_and_a_state() -> None:
    class ActionOnly:
        def predict(self, observation: Any, **_: Any) -> np.ndarray:
            return np.zeros(2)

    with pytest.raises(RolloutError, match=r"must return \(action, state\)"):
        rollout(CountingEnv(), ActionOnly(), seed=0)  # type: ignore[arg-type]


def test_an_object_without_predict_is_refused_with_the_adapter_named() -> None:
    with pytest.raises(TypeError, match="FunctionPolicy"):
        rollout(CountingEnv(), lambda obs: np.zeros(2), seed=0)  # type: ignore[arg-type]


def test_the_frame_recorder_renders_the_reset_and_every_stride_th_step() -> None:
    frames = FrameRecorder(stride=2)
    rollout(
        CountingEnv(limit=5),
        RecordingPolicy(),
        seed=0,
        on_reset=frames.on_reset,
        on_step=frames.on_step,
    )
    assert [int(f[0, 0, 0]) for f in frames.frames] == [0, 2, 4]


def test_a_pen_task_rollout_is_the_same_from_the_same_seed() -> None:
    """The expert on a real task, twice: the same trajectory (the rollout keeps no state)."""
    from ias_gym.baselines.policies import load_policy

    env = gym.make("IAS-PenRotate-v0", duration=0.3, settle_time=0.1)
    policy = load_policy("expert", env)
    first = rollout(env, policy, seed=4)
    second = rollout(env, policy, seed=4)
    env.close()
    assert 1 <= first.length == second.length <= 30
    assert first.observations is not None and second.observations is not None
    np.testing.assert_array_equal(first.observations, second.observations)
    np.testing.assert_array_equal(first.actions, second.actions)
    assert first.episode_return == second.episode_return
