"""Offline RL on Minari datasets (``ias_gym.learning.offline``, ``train/offline_rl.py``), tiny.

Datasets are written under a temporary ``MINARI_DATASETS_PATH`` (nothing in ``~``) and read
back through ``minari.load_dataset``: the conversion keeps every transition and its terminal
flag, a dataset of another env or an empty one is refused in one line (exit 2 from the
script), and a few gradient steps of each algorithm give a policy whose actions have the
env's shape and lie within its bounds.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")
pytest.importorskip("d3rlpy")
pytest.importorskip("stable_baselines3")

from minari.data_collector.episode_buffer import EpisodeBuffer  # noqa: E402

import ias_gym  # noqa: E402, F401
from ias_gym.errors import OfflineDatasetError  # noqa: E402
from ias_gym.learning.offline import (  # noqa: E402
    ALGORITHMS,
    load_offline_dataset,
    normalised_score,
    train_offline,
)
from tests.train_scripts import load_train_script  # noqa: E402

ENV_ID = "IAS-PenSlide-v0"
#: (steps, terminated) of the synthetic episodes: a time limit, a dropped pen, a time limit.
EPISODES = ((6, False), (4, True), (5, False))


@pytest.fixture(autouse=True)
def _datasets(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    path = tmp_path / "datasets"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(path))
    return path


def write_dataset(
    dataset_id: str, env_id: str = ENV_ID, episodes: tuple[tuple[int, bool], ...] = EPISODES
) -> None:
    """A Minari dataset of ``env_id``'s spaces with random observations and small actions."""
    env = gym.make(env_id)
    obs_dim = env.observation_space.shape[0]
    act_dim = env.action_space.shape[0]
    rng = np.random.default_rng(0)
    buffers = [
        EpisodeBuffer(
            id=i,
            observations=rng.normal(size=(steps + 1, obs_dim)),
            actions=rng.uniform(-0.05, 0.05, (steps, act_dim)).astype(np.float32),
            rewards=list(rng.uniform(0.0, 2.0, steps)),
            terminations=[False] * (steps - 1) + [terminated],
            truncations=[False] * (steps - 1) + [not terminated],
            infos={},
        )
        for i, (steps, terminated) in enumerate(episodes)
    ]
    with pytest.warns(UserWarning):  # minari asks for an author, a description, ...
        minari.create_dataset_from_buffers(
            dataset_id,
            buffer=buffers,
            env=gym.spec(env_id),
            observation_space=env.observation_space,
            action_space=env.action_space,
        )
    env.close()


def test_the_conversion_keeps_every_transition_and_its_terminal_flag() -> None:
    write_dataset("test/slide-v0")
    source = minari.load_dataset("test/slide-v0")
    data = load_offline_dataset("test/slide-v0", ENV_ID)

    assert data.episodes == source.total_episodes == len(EPISODES)
    assert data.transitions == data.mdp.transition_count == source.total_steps == 15
    assert data.terminated_episodes == 1
    assert data.observations.shape == (15, 67) and data.actions.shape == (15, 12)
    picker = data.mdp.transition_picker
    assert len(data.mdp.episodes) == len(EPISODES)
    for episode, minari_episode, (steps, terminated) in zip(
        data.mdp.episodes, source.iterate_episodes(), EPISODES, strict=True
    ):
        assert episode.transition_count == steps
        transitions = [picker(episode, i) for i in range(steps)]
        flags = [t.terminal for t in transitions]
        assert flags == [0.0] * (steps - 1) + [1.0 if terminated else 0.0]
        for i, t in enumerate(transitions):
            np.testing.assert_allclose(t.observation, minari_episode.observations[i], rtol=1e-6)
            np.testing.assert_allclose(t.action, minari_episode.actions[i], rtol=1e-6)
            np.testing.assert_allclose(t.reward, [minari_episode.rewards[i]], rtol=1e-6)
        if not terminated:  # a time limit: the final observation is the last next observation
            np.testing.assert_allclose(
                transitions[-1].next_observation, minari_episode.observations[-1], rtol=1e-6
            )
    first = next(source.iterate_episodes())
    np.testing.assert_allclose(data.actions[:6], first.actions, rtol=1e-6)


def test_a_dataset_of_another_env_is_refused_naming_both() -> None:
    write_dataset("test/rotate-v0", env_id="IAS-PenRotate-v0")
    with pytest.raises(OfflineDatasetError, match=r"'test/rotate-v0' was recorded on 'IAS-PenRot"):
        load_offline_dataset("test/rotate-v0", ENV_ID)


def test_an_empty_or_missing_dataset_is_refused() -> None:
    write_dataset("test/empty-v0", episodes=())
    with pytest.raises(OfflineDatasetError, match=r"'test/empty-v0' is empty"):
        load_offline_dataset("test/empty-v0", ENV_ID)
    with pytest.raises(OfflineDatasetError, match=r"'test/none-v0' cannot be loaded"):
        load_offline_dataset("test/none-v0", ENV_ID)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_tiny_training_gives_actions_of_the_env_within_its_bounds(algorithm: str) -> None:
    write_dataset("test/slide-v0")
    data = load_offline_dataset("test/slide-v0", ENV_ID)
    trained = train_offline(data, algorithm, 1 if algorithm == "sb3_bc" else 8, 0, progress=False)
    space = gym.make(ENV_ID).action_space
    action, state = trained.policy.predict(data.observations[0])
    assert action.shape == space.shape and state is None
    batch, _ = trained.policy.predict(data.observations[:5])
    assert batch.shape == (5, *space.shape)
    assert np.isfinite(batch).all()
    assert (batch >= space.low).all() and (batch <= space.high).all()
    np.testing.assert_allclose(batch[0], action, rtol=1e-5, atol=1e-7)


def test_the_normalised_score_puts_random_at_0_and_expert_at_100() -> None:
    assert normalised_score(1.0, 1.0, 101.0) == 0.0
    assert normalised_score(101.0, 1.0, 101.0) == 100.0
    assert normalised_score(51.0, 1.0, 101.0) == 50.0
    with pytest.raises(ValueError, match="must exceed"):
        normalised_score(1.0, 5.0, 5.0)


@pytest.mark.parametrize(
    ("dataset", "env_id", "episodes", "expected"),
    [
        ("test/rotate-v0", "IAS-PenRotate-v0", EPISODES, "was recorded on 'IAS-PenRotate-v0'"),
        ("test/empty-v0", ENV_ID, (), "'test/empty-v0' is empty"),
    ],
)
def test_the_script_refuses_bad_data_in_one_line_with_exit_2(
    dataset: str,
    env_id: str,
    episodes: tuple[tuple[int, bool], ...],
    expected: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    write_dataset(dataset, env_id=env_id, episodes=episodes)
    script = load_train_script("offline_rl")
    out = tmp_path / "out.json"
    argv = ["--dataset-id", dataset, "--algo", "bc", "--eval-seed", "0", "--set", "development"]
    assert script.main([*argv, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    out.write_text("{}")  # an existing output is refused before any work
    assert script.main([*argv, "--json", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert json.loads(out.read_text()) == {}


def test_the_table_collects_cells_and_refuses_a_second_run_of_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = load_train_script("offline_table")
    cell = {
        "env": ENV_ID,
        "dataset_id": "test/slide-v0",
        "algorithm": "bc",
        "runs": [],
        "command": "python train/offline_rl.py ...",
        "set": "development",
        "eval_seeds": [0, 9],
    }
    run = tmp_path / "bc.json"
    run.write_text(json.dumps(cell))
    out = tmp_path / "table.json"
    assert table.main([str(run), "--out", str(out)]) == 0
    written = json.loads(out.read_text())
    assert written["cells"] == [cell] and "pen-human" in written["reference"]["dataset"]
    assert table.main([str(run), str(run), "--out", str(tmp_path / "two.json")]) == 2
    assert "a second run of bc" in capsys.readouterr().err
    assert not (tmp_path / "two.json").exists()
