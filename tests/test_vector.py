"""Vector envs: Gymnasium's sync and async vector envs, SB3's, and the batched one of
``ias_gym.runtime.vector_env`` give every sub-env the trajectory of a single env seeded
``seed + i``, with each library's autoreset convention; the batched one's workers end on
close and a dead worker is an error, not a hang."""

from __future__ import annotations

import os
import time
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import SubprocVecEnv

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.errors import InputError, WorkerError
from ias_gym.learning.finetune import make_vec_env
from ias_gym.learning.training_envs import make_batched_vec_env
from ias_gym.registration import ENV_SPECS
from ias_gym.runtime.sb3_vec_env import BatchedVecEnv
from ias_gym.runtime.vector_env import BatchedVectorEnv, make_batched_vec

PEN = "IAS-PenSlide-v0"
#: fork: starts in milliseconds (the default of the platform here; forkserver is tested once)
CTX = "fork"


def _actions(space: gym.Space[Any], n: int, steps: int, seed: int = 0) -> list[np.ndarray]:
    """Random actions of a batch, large enough that the pen drops: episodes end."""
    rng = np.random.default_rng(seed)
    shape = (n, *space.shape)  # type: ignore[misc]
    return [rng.uniform(-1, 1, shape).astype(np.float32) for _ in range(steps)]


def _single_runs(
    env_id: str, seeds: list[int], actions: list[np.ndarray], **kwargs: Any
) -> list[list[tuple[Any, ...]]]:
    """Each sub-env's (obs, reward, terminated, truncated) per step as single envs give them,
    with Gymnasium's next-step autoreset done by hand: after an episode ends, the next step
    is ``env.reset()`` (no new seed), reward 0, not terminated, not truncated."""
    runs = []
    for i, seed in enumerate(seeds):
        env = gym.make(env_id, **kwargs)
        obs, _ = env.reset(seed=seed)
        run: list[tuple[Any, ...]] = [(obs,)]
        done = False
        for a in actions:
            if done:
                obs, _ = env.reset()
                run.append((obs, 0.0, False, False))
                done = False
            else:
                obs, r, te, tr, _ = env.step(a[i])
                run.append((obs, r, te, tr))
                done = te or tr
        runs.append(run)
        env.close()
    return runs


def _vector_run(vec: Any, seed: int, actions: list[np.ndarray]) -> list[list[tuple[Any, ...]]]:
    obs, _ = vec.reset(seed=seed)
    runs: list[list[tuple[Any, ...]]] = [[(obs[i],)] for i in range(vec.num_envs)]
    for a in actions:
        obs, r, te, tr, _ = vec.step(a)
        for i in range(vec.num_envs):
            runs[i].append((obs[i], r[i], te[i], tr[i]))
    return runs


def _assert_runs_equal(got: list[list[tuple[Any, ...]]], want: list[list[tuple[Any, ...]]]):
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want, strict=True)):
        for t, (gs, ws) in enumerate(zip(g, w, strict=True)):
            for x, y in zip(gs, ws, strict=True):
                assert np.array_equal(x, y), f"sub-env {i}, step {t}: {x} != {y}"


def _episode_ends(runs: list[list[tuple[Any, ...]]]) -> int:
    return sum(bool(s[2] or s[3]) for run in runs for s in run[1:])


def _assert_infos_equal(a: Any, b: Any, path: str = "info") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{path}: keys {set(a) ^ set(b)}"
        for k in a:
            _assert_infos_equal(a[k], b[k], f"{path}[{k!r}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_infos_equal(x, y, f"{path}[{i}]")
    else:
        assert np.array_equal(a, b), f"{path}: {a} != {b}"


# ---------------------------------------------------------------------- gymnasium's own


@pytest.mark.parametrize("env_id", sorted(ENV_SPECS))
@pytest.mark.parametrize("mode", ["sync", "async"])
def test_gym_make_vec_gives_each_sub_env_its_single_env_trajectory(env_id: str, mode: str):
    """Every registered id in Gymnasium's sync and async vector envs: the spaces are the
    batched single spaces and sub-env i of reset(seed=s) runs as a single env seeded s + i,
    across the next-step autoresets (GloveGrasp's episodes do not end in 12 steps)."""
    n, seed = 2, 11
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode=mode)
    single = gym.make(env_id)
    assert vec.single_observation_space == single.observation_space
    assert vec.single_action_space == single.action_space
    assert vec.observation_space == batch_space(single.observation_space, n)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    actions = _actions(single.action_space, n, 12 if env_id != PEN else 40)
    single.close()
    got = _vector_run(vec, seed, actions)
    vec.close()
    want = _single_runs(env_id, [seed, seed + 1], actions)
    _assert_runs_equal(got, want)
    if env_id == PEN:
        assert _episode_ends(want) >= 1  # the autoreset was exercised


# ---------------------------------------------------------------------- the batched one


@pytest.mark.parametrize("n, workers", [(1, 1), (5, 2), (4, 4)])
def test_batched_sub_envs_run_as_single_envs_seeded_s_plus_i(n: int, workers: int) -> None:
    """Any split of the envs over the workers (one batch, uneven batches, one env each)."""
    seed = 3
    actions = _actions(gym.make(PEN).action_space, n, 40)
    with make_batched_vec(PEN, n, workers, context=CTX) as vec:
        assert vec.num_workers == workers
        got = _vector_run(vec, seed, actions)
    want = _single_runs(PEN, [seed + i for i in range(n)], actions)
    _assert_runs_equal(got, want)
    assert _episode_ends(want) >= n  # every sub-env went through an autoreset


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_batched_equals_gymnasiums_sync_vector_env_infos_included(mode: AutoresetMode) -> None:
    """Same observations, rewards, flags and the same info dicts (with their ``_key`` masks,
    and ``final_obs``/``final_info`` of same-step autoreset) as SyncVectorEnv."""
    n, seed = 3, 21
    actions = _actions(gym.make(PEN).action_space, n, 40, seed=1)
    sync = gym.make_vec(PEN, n, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode})
    ended = 0
    with make_batched_vec(PEN, n, 2, context=CTX, autoreset_mode=mode) as vec:
        assert vec.metadata["autoreset_mode"] == mode
        first, first_want = vec.reset(seed=seed), sync.reset(seed=seed)
        np.testing.assert_array_equal(first[0], first_want[0])
        _assert_infos_equal(first[1], first_want[1])
        for a in actions:
            got, want = vec.step(a), sync.step(a)
            for x, y in zip(got[:4], want[:4], strict=True):
                np.testing.assert_array_equal(x, y)
            _assert_infos_equal(got[4], want[4])
            ended += int(np.sum(got[2] | got[3]))
            if mode == AutoresetMode.SAME_STEP and (got[2] | got[3]).any():
                assert "final_obs" in got[4]
    sync.close()
    assert ended >= 1


def test_next_step_autoreset_is_a_reset_step() -> None:
    """Gymnasium 1.x: the step after an episode ended ignores its action and returns the
    new episode's first observation, reward 0, neither terminated nor truncated."""
    seed = 5
    single = gym.make(PEN)
    single.reset(seed=seed)
    actions = _actions(single.action_space, 1, 60, seed=2)
    with make_batched_vec(PEN, 1, 1, context=CTX) as vec:
        vec.reset(seed=seed)
        t = 0
        for t, a in enumerate(actions):  # noqa: B007  (t: the step the episode ended)
            obs, r, te, tr, _ = vec.step(a)
            if te[0] or tr[0]:
                break
        else:
            pytest.fail("no episode ended in 60 random steps")
        single_done = [single.step(b[0])[2:4] for b in actions[: t + 1]][-1]
        assert any(single_done)
        obs, r, te, tr, info = vec.step(np.full((1, 12), np.nan, dtype=np.float32))
        assert (r[0], te[0], tr[0]) == (0.0, False, False)
        np.testing.assert_array_equal(obs[0], single.reset()[0])
        assert info["time"][0] == 0.0


def test_reset_mask_resets_only_those_sub_envs() -> None:
    with make_batched_vec(PEN, 3, 2, context=CTX) as vec:
        first, _ = vec.reset(seed=0)
        vec.step(np.zeros((3, 12), dtype=np.float32))
        moved = vec.step(np.zeros((3, 12), dtype=np.float32))[0]
        mask = np.array([False, True, False])
        obs, info = vec.reset(seed=[None, 1, None], options={"reset_mask": mask})
        np.testing.assert_array_equal(obs[1], first[1])  # seed 1 = the first reset's env 1
        np.testing.assert_array_equal(obs[[0, 2]], moved[[0, 2]])
        assert info["_time"].tolist() == [False, True, False]
        with pytest.raises(ValueError, match="reset_mask"):
            vec.reset(options={"reset_mask": np.zeros(3, dtype=bool)})


def test_batched_spaces_attributes_and_kwargs() -> None:
    with make_batched_vec(
        PEN, 3, 2, context=CTX, control_dt=0.02, wrappers=[gym.wrappers.RecordEpisodeStatistics]
    ) as vec:
        single = gym.make(PEN, control_dt=0.02)
        assert vec.single_observation_space == single.observation_space
        assert vec.observation_space == batch_space(single.observation_space, 3)
        assert vec.action_space == batch_space(single.action_space, 3)
        assert vec.get_attr("dt") == (0.02, 0.02, 0.02)
        info = {"max_position_error": 0.5, "slide_errors": [-0.003], "max_pen_tilt": 0.1}
        assert (
            vec.call("episode_metrics", info)
            == ({"final_slide_error": 0.003, "max_position_error": 0.5, "max_pen_tilt": 0.1},) * 3
        )
        vec.set_attr("marker", [1, 2, 3])
        assert vec.get_attr("marker") == (1, 2, 3)
        assert vec.workers.is_wrapped(gym.wrappers.RecordEpisodeStatistics) == [True] * 3
        with pytest.raises(ValueError, match="shape"):
            vec.step(np.zeros((2, 12)))


def test_an_env_error_is_raised_with_its_type_and_the_env_goes_on() -> None:
    with make_batched_vec(PEN, 2, 2, context=CTX) as vec:
        vec.reset(seed=0)
        bad = np.zeros((2, 12), dtype=np.float32)
        bad[1, 0] = np.nan
        with pytest.raises(ValueError, match="NaN") as raised:
            vec.step(bad)
        assert "BatchedWorkers process" in "".join(raised.value.__notes__)
        obs, *_ = vec.step(np.zeros((2, 12), dtype=np.float32))  # still usable
        assert np.isfinite(obs).all()


class _DiesOnBigAction(gym.Wrapper[Any, Any, Any, Any]):
    """Kills its process (as a segfault would) when action[0] > 5."""

    def step(self, action: Any) -> Any:
        if action[0] > 5:
            os._exit(3)
        return self.env.step(action)


def test_a_dead_worker_is_a_clear_error_not_a_hang_and_close_ends_all_workers() -> None:
    vec = make_batched_vec(PEN, 4, 2, context=CTX, wrappers=[_DiesOnBigAction])
    procs = list(vec.workers._procs)
    vec.reset(seed=0)
    actions = np.zeros((4, 12), dtype=np.float32)
    actions[3, 0] = 10.0  # env 3 is in worker 1
    start = time.monotonic()
    with pytest.raises(WorkerError, match=r"worker 1 .*envs 2\.\.3.*\(exit code 3\)"):
        vec.step(actions)
    assert time.monotonic() - start < 10.0
    with pytest.raises(WorkerError, match="died"):
        vec.step(np.zeros((4, 12), dtype=np.float32))  # and it stays broken
    vec.close()
    for proc in procs:
        proc.join(5.0)
        assert not proc.is_alive()


def test_workers_end_on_close_and_a_closed_env_refuses_steps() -> None:
    vec = make_batched_vec(PEN, 3, 3, context=CTX)
    vec.reset(seed=0)
    procs = list(vec.workers._procs)
    vec.close()
    assert all(p.exitcode == 0 for p in procs)  # ended by themselves, after closing envs
    with pytest.raises(WorkerError, match="closed"):
        vec.step(np.zeros((3, 12), dtype=np.float32))


def _fails_in_a_child() -> gym.Env[Any, Any]:
    if os.getpid() != _PARENT:
        raise RuntimeError("no device in this process")
    return gym.make(PEN)


_PARENT = os.getpid()


def test_an_env_that_cannot_be_built_in_a_worker_raises_at_construction() -> None:
    with pytest.raises(RuntimeError, match="no device in this process"):
        BatchedVectorEnv([_fails_in_a_child] * 2, 2, context=CTX, timeout=30)


def test_bad_sizes_are_input_errors() -> None:
    with pytest.raises(InputError, match="num_workers"):
        make_batched_vec(PEN, 2, 3, context=CTX)
    with pytest.raises(InputError, match="num_envs"):
        make_batched_vec(PEN, 0, context=CTX)


# ---------------------------------------------------------------------- SB3


def test_sb3_batched_vec_env_equals_dummy_vec_env_with_sb3_conventions() -> None:
    """The SB3 adapter against SB3's DummyVecEnv of the same envs (Monitor, reward scale,
    seeds): same observations, rewards, dones; a finished episode's last observation in
    ``terminal_observation``, ``TimeLimit.truncated``, Monitor's ``episode`` record."""
    n = 3
    batched = make_batched_vec_env(PEN, n, seed=4, num_workers=2, context=CTX)
    dummy = make_vec_env(PEN, n, seed=4)
    assert batched.observation_space == dummy.observation_space
    assert batched.action_space == dummy.action_space
    np.testing.assert_array_equal(batched.reset(), dummy.reset())
    ends = 0
    for a in _actions(dummy.action_space, n, 50, seed=3):
        got, want = batched.step(a), dummy.step(a)
        for x, y in zip(got[:3], want[:3], strict=True):
            np.testing.assert_array_equal(x, y)
            assert np.asarray(x).dtype == np.asarray(y).dtype
        for gi, wi in zip(got[3], want[3], strict=True):
            assert set(gi) == set(wi)
            assert gi["TimeLimit.truncated"] == wi["TimeLimit.truncated"]
            if "terminal_observation" in wi:
                ends += 1
                np.testing.assert_array_equal(
                    gi["terminal_observation"], wi["terminal_observation"]
                )
                assert gi["episode"]["r"] == wi["episode"]["r"]
                assert gi["episode"]["l"] == wi["episode"]["l"]
    assert ends >= n
    assert batched.env_is_wrapped(Monitor) == [True] * n
    assert batched.get_attr("dt", indices=[1]) == [0.01]
    batched.close()
    dummy.close()


class _Zero:
    """A deterministic policy for evaluate_policy: zero torques."""

    def predict(self, obs: np.ndarray, *args: Any, **kwargs: Any) -> tuple[np.ndarray, None]:
        return np.zeros((len(obs), 12), dtype=np.float32), None


def test_sb3_evaluate_policy_runs_on_the_batched_env_as_on_a_dummy_one() -> None:
    rotate, short = "IAS-PenRotate-v0", {"duration": 0.3, "settle_time": 0.1}
    batched = make_batched_vec_env(
        rotate, 2, seed=9, num_workers=2, context=CTX, env_kwargs=short, reward_scale=1.0
    )
    dummy = make_vec_env(rotate, 2, seed=9, env_kwargs=short, reward_scale=1.0)
    policy: Any = _Zero()
    got = evaluate_policy(policy, batched, n_eval_episodes=4, return_episode_rewards=True)
    want = evaluate_policy(policy, dummy, n_eval_episodes=4, return_episode_rewards=True)
    assert got == want
    assert len(got[0]) == 4  # type: ignore[arg-type]
    batched.close()


@pytest.mark.parametrize("env_id", sorted(ENV_SPECS))
def test_sb3_subproc_vec_env_works_for_every_id(env_id: str) -> None:
    """SB3's own SubprocVecEnv (through its make_vec_env): sub-env i is seeded s + i."""
    vec = sb3_make_vec_env(
        env_id, n_envs=2, seed=6, vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": CTX}
    )
    single = gym.make(env_id)
    assert vec.observation_space == single.observation_space
    obs: Any = vec.reset()
    np.testing.assert_array_equal(obs[1], single.reset(seed=7)[0])
    a = _actions(single.action_space, 2, 1)[0]
    obs = vec.step(a)[0]
    np.testing.assert_array_equal(obs[1], single.step(a[1])[0])
    vec.close()


def test_sb3_batched_vec_env_starts_with_forkserver_too() -> None:
    """The adapter's default start method (SB3's): workers rebuild the envs from pickles."""
    vec = BatchedVecEnv([lambda: gym.make(PEN)] * 2, 2)
    vec.seed(1)
    obs: Any = vec.reset()
    np.testing.assert_array_equal(obs[1], gym.make(PEN).reset(seed=2)[0])
    vec.close()


# ---------------------------------------------------------------------- the glove hardware


@pytest.mark.realtime
def test_the_hardware_env_vectorises_from_a_recorded_session(channel: str, tmp_path: Any) -> None:
    """IAS-GloveHardware-v0 needs a device; a recorded session (replay=, no bus) is one that
    every worker can open: sync, async and batched give each sub-env the single replay."""
    from ias_gym.hardware import GloveEmulator

    log = tmp_path / "session.blf"
    zero = np.zeros(10, dtype=np.float32)
    with GloveEmulator(channel=channel, rate_hz=500, watchdog_timeout=0.2):
        env = gym.make(
            "IAS-GloveHardware-v0",
            channel=channel,
            record=log,
            control_dt=0.004,
            watchdog_timeout=0.2,
        )
        env.reset(seed=0)
        for _ in range(30):
            env.step(zero)
        env.close()
    kwargs = {"replay": log, "control_dt": 0.004}
    single = gym.make("IAS-GloveHardware-v0", **kwargs)
    want = [single.reset(seed=0)[0]] + [single.step(zero)[0] for _ in range(20)]
    single.close()
    vecs = [
        gym.make_vec("IAS-GloveHardware-v0", 2, vectorization_mode="sync", **kwargs),
        gym.make_vec(
            "IAS-GloveHardware-v0",
            2,
            vectorization_mode="async",
            vector_kwargs={"context": CTX},
            **kwargs,
        ),
        make_batched_vec("IAS-GloveHardware-v0", 2, 2, context=CTX, **kwargs),
    ]
    for vec in vecs:
        got = [vec.reset(seed=0)[0]] + [vec.step(np.stack([zero, zero]))[0] for _ in range(20)]
        vec.close()
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g[0], w)
            np.testing.assert_array_equal(g[1], w)


def test_training_envs_are_batched_for_more_than_one_env() -> None:
    """train/*.py --n-envs N: one env in this process, N > 1 batched, the same envs."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ias_gym.learning.training_envs import make_training_env

    one = make_training_env(PEN, 1, seed=3)
    assert isinstance(one, DummyVecEnv)
    many = make_training_env(PEN, 3, seed=3, num_workers=2, context=CTX)
    assert isinstance(many, BatchedVecEnv) and many.num_workers == 2
    same = make_vec_env(PEN, 3, seed=3)
    first: Any = same.reset()
    np.testing.assert_array_equal(many.reset(), first)
    np.testing.assert_array_equal(one.reset(), first[:1])
    for env in (one, many, same):
        env.close()
    with pytest.raises(InputError, match="n_envs"):
        make_training_env(PEN, 0)
