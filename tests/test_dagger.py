"""DAgger with the analytic expert as teacher: the labels, the randomisation, the saved policy,
bad input. Tiny budgets (episodes of 30 steps, a few cloning epochs); properties, not numbers.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from ias_gym.baselines.expert import ExpertPolicy  # noqa: E402
from ias_gym.baselines.policies import ModelPolicy, load_policy  # noqa: E402
from ias_gym.errors import InputError  # noqa: E402
from ias_gym.learning.dagger import DaggerResult, cloning_epochs, dagger  # noqa: E402
from ias_gym.learning.expert_labelling import collect_episode, expert_dataset  # noqa: E402
from ias_gym.learning.randomised_dynamics import (  # noqa: E402
    DEFAULT_RANDOMISATION,
    HELD_OUT_SEED_START,
    OBSERVATION_NOISE,
    SINGLE_FAMILIES,
    EpisodeDynamics,
    Randomisation,
    episode_dynamics,
)
from ias_gym.robustness import DISTURBANCES  # noqa: E402
from tests.train_scripts import load_train_script  # noqa: E402

ENV_ID = "IAS-PenRotate-v0"
#: 30 steps of 10 ms; the tilt judged over the last 0.1 s (as in test_learning).
ENV_KWARGS: dict[str, Any] = {"duration": 0.3, "settle_time": 0.2}


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def run() -> DaggerResult:
    """Two DAgger iterations of two episodes, the learner acting alone in the second."""
    torch.set_num_threads(1)
    return dagger(
        ENV_ID,
        iterations=2,
        episodes_per_iteration=2,
        seed=3,
        beta_decay=0.0,
        env_kwargs=ENV_KWARGS,
        epochs=5,
        net_arch=(32, 32),
        keep_models=True,
        progress=False,
    )


def _replayed_labels(
    dynamics: EpisodeDynamics, actions: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Step a fresh env with ``actions`` from the episode's reset, a fresh expert labelling
    each state: the observations and the expert's actions on them."""
    env = gym.make(ENV_ID, **{**ENV_KWARGS, **dynamics.env_kwargs})
    expert = ExpertPolicy(env)
    obs, _ = env.reset(seed=dynamics.seed)
    observations, labels = [], []
    for t, action in enumerate(actions):
        observations.append(obs)
        labels.append(expert.predict(obs, episode_start=t == 0)[0])
        obs, *_ = env.step(action)
    env.close()
    return np.asarray(observations), np.asarray(labels)


def test_an_iteration_labels_exactly_the_states_the_learner_visited(run: DaggerResult) -> None:
    result = run
    first, second = result.history
    assert second.beta == 0.0 and second.expert_fraction == 0.0
    assert first.dataset_size == first.labels_added
    assert second.dataset_size == first.dataset_size + second.labels_added
    assert len(result.dataset) == second.dataset_size
    learner = result.models[0]
    rows = slice(first.dataset_size, None)
    new_obs = result.dataset.observations[rows]
    new_labels = result.dataset.actions[rows]
    kept = 0
    offset = 0
    for k in range(second.episodes):
        dynamics = episode_dynamics(3, second.episodes + k)
        episode = collect_episode(ENV_ID, dynamics, learner, 0.0, env_kwargs=ENV_KWARGS)
        trajectory = episode.trajectory
        steps = trajectory.length
        assert steps == len(episode.labels) > 0
        # the visited states: every observation the learner acted on, none other
        assert trajectory.observations is not None
        np.testing.assert_array_equal(episode.observations, trajectory.observations[:-1])
        # the dataset holds those where the expert's grasp model held, in order
        observations, labels = episode.teaching_pairs()
        assert len(labels) == int(episode.held.sum())
        np.testing.assert_array_equal(new_obs[kept : kept + len(labels)], observations)
        np.testing.assert_array_equal(new_labels[kept : kept + len(labels)], labels)
        kept += len(labels)
        # the learner acted ...
        acted = learner.predict(episode.observations.astype(np.float32), deterministic=True)[0]
        np.testing.assert_allclose(trajectory.actions, acted, rtol=1e-6, atol=1e-7)
        # ... and the labels are the expert's actions on those states
        observations, labels = _replayed_labels(dynamics, trajectory.actions)
        np.testing.assert_array_equal(observations, episode.observations)
        np.testing.assert_allclose(episode.labels, labels, rtol=1e-6, atol=1e-7)
        offset += steps
    assert kept == second.labels_added <= offset


def test_the_expert_alone_labels_its_own_actions() -> None:
    dynamics = episode_dynamics(0, 0)
    episode = collect_episode(ENV_ID, dynamics, None, 1.0, env_kwargs=ENV_KWARGS)
    assert episode.expert_fraction == 1.0
    np.testing.assert_array_equal(episode.trajectory.actions, episode.labels)
    assert episode.held.all()  # the expert holds the pen it carries


class _NoTorque:
    """A learner that lets go: zero torque on every joint."""

    def predict(self, observation: Any, state: Any = None, **_: Any) -> tuple[np.ndarray, Any]:
        return np.zeros(12, dtype=np.float32), state


def test_states_the_expert_cannot_hold_teach_nothing() -> None:
    """A learner that lets go drops the pen within a few steps; the states after it has
    gone are labelled (the expert runs on) but kept out of the teaching pairs."""
    dynamics = episode_dynamics(0, 0)
    episode = collect_episode(ENV_ID, dynamics, _NoTorque(), 0.0, env_kwargs=ENV_KWARGS)
    assert episode.trajectory.terminated  # dropped
    assert episode.held[0] and not episode.held[-1]
    observations, labels = episode.teaching_pairs()
    np.testing.assert_array_equal(labels, episode.labels[episode.held])
    np.testing.assert_array_equal(observations, episode.observations[episode.held])
    # what the expert asks for once the pen has gone is far from what it asks while holding
    assert np.abs(episode.labels[~episode.held]).max() > 2 * np.abs(labels).max()


def test_the_takeover_gate_hands_the_expert_the_states_a_learner_would_lose() -> None:
    """With the gate, the learner acts only where its action is within the gate of the
    expert's label: a learner that lets go then never loses the pen, which it drops without
    the gate (the test above)."""
    dynamics = episode_dynamics(0, 0)
    gate = 0.05
    episode = collect_episode(
        ENV_ID, dynamics, _NoTorque(), 0.0, env_kwargs=ENV_KWARGS, takeover=gate
    )
    assert not episode.trajectory.terminated and episode.held.all()
    learner_acted = np.all(episode.trajectory.actions == 0.0, axis=1)
    assert learner_acted.any() and episode.expert_fraction > 0.5
    assert np.abs(episode.labels[learner_acted]).max() <= gate
    # a gate wider than any label lets the learner act, and it lets go
    loose = collect_episode(ENV_ID, dynamics, _NoTorque(), 0.0, env_kwargs=ENV_KWARGS, takeover=2.0)
    assert loose.trajectory.terminated and loose.expert_fraction < 1.0


def test_noise_on_the_expert_acts_but_never_reaches_the_labels() -> None:
    dynamics = episode_dynamics(0, 0)
    episode = collect_episode(ENV_ID, dynamics, None, 1.0, env_kwargs=ENV_KWARGS, expert_noise=0.01)
    trajectory = episode.trajectory
    # every component is moved except where the env's bound clips both to +-1
    moved = np.abs(trajectory.actions - episode.labels) > 0
    assert np.all(moved | (np.abs(episode.labels) == 1.0))
    _, labels = _replayed_labels(dynamics, trajectory.actions)
    np.testing.assert_allclose(episode.labels, labels, rtol=1e-6, atol=1e-7)


def test_expert_dataset_has_exactly_the_labels_asked() -> None:
    data, episodes = expert_dataset(ENV_ID, 45, seed=1, env_kwargs=ENV_KWARGS, progress=False)
    assert len(data) == 45 and len(episodes) >= 2
    np.testing.assert_array_equal(data.actions[: len(episodes[0].labels)], episodes[0].labels)


def _inside(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= value <= bounds[1]


def test_randomisation_samples_within_the_documented_ranges() -> None:
    r = DEFAULT_RANDOMISATION
    drawn = [episode_dynamics(7, k) for k in range(600)]
    assert {d.family for d in drawn} == set(SINGLE_FAMILIES)  # one disturbance at a time
    for d in drawn:
        assert 0 <= d.seed < HELD_OUT_SEED_START
        kw = d.env_kwargs
        if d.family == "nominal":
            assert kw == {}
        elif d.family == "friction":
            assert set(kw) == {"friction_scale"} and _inside(kw["friction_scale"], r.friction_scale)
        elif d.family == "mass":
            assert set(kw) == {"mass_scale"} and _inside(kw["mass_scale"], r.mass_scale)
        elif d.family == "push":
            assert _inside(kw["push_force"], r.push_force)
            assert _inside(kw["push_duration"], r.push_duration)
        elif d.family == "observation_noise":
            scales = {kw[name] / sigma for name, sigma in OBSERVATION_NOISE.items()}
            assert len(scales) == 1 or np.ptp(list(scales)) < 1e-9
            assert _inside(scales.pop(), r.observation_noise_scale)
        elif d.family == "action_delay":
            assert isinstance(kw["action_delay"], int)
            assert _inside(kw["action_delay"], r.action_delay)
        elif d.family == "action_noise":
            assert _inside(kw["action_noise"], r.action_noise)
        else:
            assert _inside(kw["internal_force_step"], r.internal_force_step)


def test_a_combined_draw_sets_every_disturbance_inside_its_range() -> None:
    r = Randomisation(families=("combined",))
    keys = set(OBSERVATION_NOISE) | {
        "friction_scale",
        "mass_scale",
        "push_force",
        "push_duration",
        "action_delay",
        "action_noise",
        "internal_force_step",
    }
    drawn = [episode_dynamics(3, k, r) for k in range(100)]
    for d in drawn:
        kw = d.env_kwargs
        assert d.family == "combined" and set(kw) == keys
        for name in ("friction_scale", "mass_scale", "push_force", "push_duration"):
            assert _inside(kw[name], getattr(r, name))
        assert _inside(kw["action_noise"], r.action_noise)
        assert _inside(kw["internal_force_step"], r.internal_force_step)
    # the parameters vary between episodes, each on its own
    assert np.ptp([d.env_kwargs["push_force"] for d in drawn]) > 0.2
    assert {d.env_kwargs["action_delay"] for d in drawn} == {0, 1, 2}
    gym.make(ENV_ID, **ENV_KWARGS, **drawn[0].env_kwargs).close()


def test_the_suite_classes_lie_inside_the_ranges() -> None:
    r = DEFAULT_RANDOMISATION
    ranges = {
        "friction_scale": r.friction_scale,
        "mass_scale": r.mass_scale,
        "push_force": r.push_force,
        "push_duration": r.push_duration,
        "action_delay": r.action_delay,
        "action_noise": r.action_noise,
        "internal_force_step": r.internal_force_step,
    }
    for kwargs in DISTURBANCES.values():
        for name, value in kwargs.items():
            if name in OBSERVATION_NOISE:
                assert _inside(value / OBSERVATION_NOISE[name], r.observation_noise_scale)
            else:
                assert _inside(value, ranges[name]), (name, value)


def test_randomisation_is_reproducible_by_seed() -> None:
    a = [episode_dynamics(11, k) for k in range(50)]
    assert a == [episode_dynamics(11, k) for k in range(50)]
    assert a != [episode_dynamics(12, k) for k in range(50)]


def test_every_family_makes_an_env() -> None:
    seen: dict[str, dict[str, Any]] = {}
    for k in range(200):
        d = episode_dynamics(5, k)
        seen.setdefault(d.family, d.env_kwargs)
    assert set(seen) == set(SINGLE_FAMILIES)
    for kwargs in seen.values():
        gym.make(ENV_ID, **ENV_KWARGS, **kwargs).close()


def test_the_saved_policy_loads_with_the_safe_loader_and_acts(
    run: DaggerResult, tmp_path: Path
) -> None:
    path = tmp_path / "dagger.zip"
    run.model.save(path)
    env = gym.make(ENV_ID, **ENV_KWARGS)
    policy = load_policy(str(path), env)  # trust_pickle=False: no code from the file
    assert isinstance(policy, ModelPolicy)
    obs, _ = env.reset(seed=HELD_OUT_SEED_START)
    action, _ = policy.predict(obs, deterministic=True)
    assert action.shape == env.action_space.shape
    expected = run.model.predict(obs.astype(np.float32), deterministic=True)[0]
    np.testing.assert_allclose(action, expected, rtol=1e-5, atol=1e-7)
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"iterations": 0}, "iterations must be >= 1"),
        ({"episodes_per_iteration": 0}, "episodes_per_iteration must be >= 1"),
        ({"seed": -1}, "seed must be >= 0"),
        ({"beta_decay": 1.5}, "beta_decay"),
        ({"takeover": 0.0}, "takeover must be finite and > 0"),
        ({"obs_clip": float("inf")}, "obs_clip must be finite and > 0"),
        ({"obs_clip": -1.0}, "obs_clip must be finite and > 0"),
        ({"env_id": "IAS-GloveGrasp-v0"}, "not a pen task"),
        ({"env_id": "NoSuchEnv-v0"}, "unknown env id"),
    ],
)
def test_bad_input_is_a_clear_error(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"env_id": ENV_ID, "iterations": 1, "episodes_per_iteration": 1}
    with pytest.raises(InputError, match=match):
        dagger(**{**args, **kwargs}, env_kwargs=ENV_KWARGS, progress=False)  # type: ignore[arg-type]


def test_bad_ranges_are_refused() -> None:
    with pytest.raises(InputError, match="unknown randomisation families"):
        Randomisation(families=("weather",))
    with pytest.raises(InputError, match="friction_scale"):
        Randomisation(friction_scale=(1.2, 0.8))


def test_cloning_epochs_caps_the_gradient_steps() -> None:
    assert cloning_epochs(1000, 100, 256, None) == 100
    assert cloning_epochs(1000, 100, 256, 40) == 10  # 4 steps an epoch
    assert cloning_epochs(100_000, 100, 256, 10) == 1


def _script_main() -> Callable[[list[str]], int]:
    """``main`` of ``train/dagger.py``, imported in this process (no second torch import)."""
    main: Callable[[list[str]], int] = load_train_script("dagger").main
    return main


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--iterations", "0"], "--iterations must be >= 1"),
        (["--env", "IAS-GloveGrasp-v0"], "not a pen task"),
        (["--eval-seed", "5"], "--eval-seed must be >= 100000"),
        (["--takeover", "nan"], "--takeover must be a positive number"),
        (["--obs-clip", "0"], "--obs-clip must be a positive number"),
    ],
)
def test_the_script_refuses_bad_input_with_one_line(
    args: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _script_main()(["--out", str(tmp_path / "p.zip"), *args]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], lines


def test_the_script_clips_observations_as_the_library_does_by_default() -> None:
    from ias_gym.learning.normalisation import OBS_CLIP

    parser = load_train_script("dagger").build_parser()
    assert parser.get_default("obs_clip") == OBS_CLIP


def test_a_warm_start_trains_one_learner_on() -> None:
    with pytest.raises(InputError, match="keep_models needs warm_start=False"):
        dagger(ENV_ID, 1, 1, warm_start=True, keep_models=True, progress=False)
    result = dagger(
        ENV_ID,
        iterations=2,
        episodes_per_iteration=1,
        seed=2,
        env_kwargs=ENV_KWARGS,
        epochs=2,
        net_arch=(16,),
        warm_start=True,
        progress=False,
    )
    first = result.history[0].dataset_size
    extractor: Any = result.model.policy.features_extractor
    # the normalisation is iteration 0's, from the expert's states alone
    expected = result.dataset.observations[:first].mean(axis=0)
    np.testing.assert_allclose(extractor.mean.numpy(), expected, rtol=1e-4, atol=1e-6)
    assert all(r.gradient_steps >= 1 for r in result.history)


def _curve_run(env: str, ensemble: int, seed: int) -> dict[str, Any]:
    points = [
        {
            "env_steps": 1000 * (i + 1),
            "wall_time_s": 30.0 * (i + 1),
            "success_rate": r,
            "ci95_low": max(0.0, r - 0.2),
            "ci95_high": min(1.0, r + 0.2),
        }
        for i, r in enumerate((0.2, 0.6, 0.9))
    ]
    bc = {
        "env_steps": 3000,
        "wall_time_s": 40.0,
        "success_rate": 0.7,
        "ci95_low": 0.5,
        "ci95_high": 0.85,
    }
    return {
        "env": env,
        "ensemble": ensemble,
        "train_seed": seed,
        "history": [],
        "development_curve": points,
        "bc_development_point": bc,
    }


def test_the_curve_script_draws_runs_and_refuses_files_without_a_curve(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("matplotlib")
    script = load_train_script("dagger_curves")
    paths = []
    for k, (env, size) in enumerate([(ENV_ID, 1), (ENV_ID, 3), ("IAS-PenSlide-v0", 3)]):
        paths.append(tmp_path / f"run{k}.json")
        paths[-1].write_text(json.dumps(_curve_run(env, size, k)))
    out = tmp_path / "curves.png"
    assert script.main([*map(str, paths), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert script.main([*map(str, paths), "--out", str(out)]) == 2  # exists: not overwritten
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({**_curve_run(ENV_ID, 1, 0), "development_curve": []}))
    assert script.main([str(bare), "--out", str(tmp_path / "b.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--curve-episodes" in err[-1]
    assert not (tmp_path / "b.png").exists()
