"""Saved SB3 models are loaded without running code from the file (``ias_gym.safe_sb3``).

A model ``.zip`` stores what SB3 could not write as JSON as base64 cloudpickle under a
``":serialized:"`` key of its ``data`` JSON, and tensors as ``*.pth``; SB3's own ``load``
unpickles all of it. The malicious files below carry a pickle whose ``__reduce__`` creates a
marker file when it is unpickled: the marker must never appear unless ``trust_pickle`` is
given, and a genuine model must act exactly as SB3's own load of it does.
"""

from __future__ import annotations

import base64
import io
import json
import pickle
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")
sb3 = pytest.importorskip("stable_baselines3")

from stable_baselines3.common.torch_layers import BaseFeaturesExtractor  # noqa: E402

from ias_gym.cli import main  # noqa: E402
from ias_gym.evaluation import load_policy  # noqa: E402
from ias_gym.learning.normalisation import policy_kwargs  # noqa: E402
from ias_gym.safe_sb3 import (  # noqa: E402
    TRUST_HINT,
    PolicyFileError,
    UntrustedPickleError,
    load_sb3_policy,
)

ENV_ID = "IAS-PenRotate-v0"
# [s]: 5 steps; the tilt error is judged from the start (the default 1 s outlasts them).
ENV_KWARGS = {"duration": 0.05, "settle_time": 0.0}


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _env() -> gym.Env[Any, Any]:
    return gym.make(ENV_ID, **ENV_KWARGS)


class _Payload:
    """Unpickling this creates ``marker``: what an attacker's code would do, harmlessly."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (open, (str(self.marker), "w"))


def _serialized(marker: Path, **json_fields: Any) -> dict[str, Any]:
    """A field the way SB3's data_to_json stores a non-JSON object, with the payload."""
    blob = base64.b64encode(pickle.dumps(_Payload(marker))).decode()
    return {":type:": "<class 'abc.ABCMeta'>", ":serialized:": blob, **json_fields}


def _rewrite(
    src: Path,
    dst: Path,
    data: Callable[[dict[str, Any]], None] | None = None,
    members: dict[str, bytes] | None = None,
) -> Path:
    """Copy the model zip ``src`` to ``dst`` with its data JSON edited / members replaced."""
    with zipfile.ZipFile(src) as old, zipfile.ZipFile(dst, "w") as new:
        for name in old.namelist():
            raw = old.read(name)
            if name == "data" and data is not None:
                content = json.loads(raw)
                data(content)
                raw = json.dumps(content).encode()
            if members and name in members:
                raw = members[name]
            new.writestr(name, raw)
    return dst


def _torch_payload(marker: Path) -> bytes:
    buffer = io.BytesIO()
    torch.save({"x": _Payload(marker)}, buffer)
    return buffer.getvalue()


class TinyExtractor(BaseFeaturesExtractor):
    """A features extractor of the user's own: not on the loader's allow-list."""

    def __init__(self, observation_space: gym.spaces.Box) -> None:
        super().__init__(observation_space, features_dim=int(np.prod(observation_space.shape)))
        self.flatten = torch.nn.Flatten()

    def forward(self, observations: Any) -> Any:
        return self.flatten(observations)


def _perturb(model: Any, seed: int) -> None:
    """Move every weight off its initial value: a loader that ignored policy.pth would
    then act differently from the saved model."""
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.policy.parameters():
            p.add_(0.3 * torch.randn(p.shape, generator=generator))


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Tiny saved PPO (with ias_gym's normaliser, tanh) and SAC (SB3's defaults, ReLU)."""
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("models")
    env = _env()
    space = env.observation_space
    rng = np.random.default_rng(0)
    mean, std = rng.normal(size=space.shape), rng.uniform(0.5, 2.0, size=space.shape)
    ppo = sb3.PPO(
        "MlpPolicy",
        env,
        n_steps=16,
        batch_size=16,
        n_epochs=1,
        policy_kwargs=policy_kwargs(mean, std, (16,)),
        device="cpu",
        seed=0,
    )
    ppo.learn(total_timesteps=16)
    _perturb(ppo, 1)
    ppo.save(out / "ppo.zip")
    sac = sb3.SAC("MlpPolicy", env, policy_kwargs={"net_arch": [16]}, device="cpu", seed=0)
    _perturb(sac, 2)
    sac.save(out / "sac.zip")
    custom = sb3.PPO(
        "MlpPolicy", env, policy_kwargs={"features_extractor_class": TinyExtractor}, device="cpu"
    )
    custom.save(out / "custom.zip")
    return {"ppo": out / "ppo.zip", "sac": out / "sac.zip", "custom": out / "custom.zip"}


def _observations(n: int = 16) -> np.ndarray:
    """Observations of the env itself and far outside it (the clipping must agree too)."""
    env = _env()
    obs = [env.reset(seed=s)[0] for s in range(n // 2)]
    rng = np.random.default_rng(3)
    return np.concatenate([np.stack(obs), 5 * rng.normal(size=(n - len(obs), len(obs[0])))])


@pytest.mark.parametrize(("name", "algorithm"), [("ppo", "PPO"), ("sac", "SAC")])
def test_safe_load_acts_as_sb3_load_without_unpickling(
    models: dict[str, Path], name: str, algorithm: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = models[name]
    reference = getattr(sb3, algorithm).load(path, device="cpu")
    expected = np.stack([reference.predict(o, deterministic=True)[0] for o in _observations()])

    import cloudpickle

    def no_unpickling(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("the loader unpickled a field of the model file")

    monkeypatch.setattr(cloudpickle, "loads", no_unpickling)
    monkeypatch.setattr(pickle, "loads", no_unpickling)
    act = load_policy(str(path), _env())  # what `ias-gym evaluate --policy FILE` uses
    actions = np.stack([act.predict(o)[0] for o in _observations()])
    np.testing.assert_array_equal(actions, expected)
    assert np.ptp(actions) > 0.01  # not a constant (e.g. clipped or untrained) policy
    assert load_sb3_policy(path, _env()).algorithm == algorithm


def test_malicious_class_field_is_refused_and_never_runs(
    models: dict[str, Path], tmp_path: Path
) -> None:
    """policy_class stored only as a pickle (no class name in its JSON description)."""
    marker = tmp_path / "pwned"

    def evil(data: dict[str, Any]) -> None:
        data["policy_class"] = _serialized(marker)

    path = _rewrite(models["ppo"], tmp_path / "evil.zip", evil)
    with pytest.raises(UntrustedPickleError, match="--trust-pickle") as info:
        load_policy(str(path), _env())
    assert "policy_class" in str(info.value) and "trust_pickle=True" in str(info.value)
    assert not marker.exists()


def test_malicious_policy_kwargs_class_is_refused(models: dict[str, Path], tmp_path: Path) -> None:
    marker = tmp_path / "pwned"

    def evil(data: dict[str, Any]) -> None:
        data["policy_kwargs"] = {
            **_serialized(marker),
            ":type:": "<class 'dict'>",
            "net_arch": [16],
            "activation_fn": "<class 'posix.system'>",
        }

    path = _rewrite(models["ppo"], tmp_path / "evil.zip", evil)
    with pytest.raises(UntrustedPickleError, match=r"activation_fn.*posix\.system.*--trust-pickle"):
        load_policy(str(path), _env())
    assert not marker.exists()


@pytest.mark.parametrize("where", ["lr_schedule", "observation_space", "optimizer", "variables"])
def test_payloads_in_fields_acting_does_not_need_never_run(
    models: dict[str, Path], tmp_path: Path, where: str
) -> None:
    """Training-only fields, a space with its JSON description, the optimiser state and the
    extra tensors: the model loads and acts as saved, and no payload runs."""
    marker = tmp_path / "pwned"

    def evil(data: dict[str, Any]) -> None:
        if where == "lr_schedule":
            data["lr_schedule"] = _serialized(marker)
        if where == "observation_space":
            description = {k: v for k, v in data["observation_space"].items() if k[0] != ":"}
            data["observation_space"] = {
                **_serialized(marker, **description),
                ":type:": "<class 'gymnasium.spaces.box.Box'>",
            }

    members = {
        "optimizer": {"policy.optimizer.pth": _torch_payload(marker)},
        "variables": {"pytorch_variables.pth": _torch_payload(marker)},
    }.get(where)
    path = _rewrite(models["ppo"], tmp_path / "evil.zip", evil, members)
    act = load_policy(str(path), _env())
    genuine = load_policy(str(models["ppo"]), _env())
    for obs in _observations(4):
        np.testing.assert_array_equal(act.predict(obs)[0], genuine.predict(obs)[0])
    assert not marker.exists()


def test_weights_holding_objects_are_refused(models: dict[str, Path], tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    path = _rewrite(
        models["ppo"], tmp_path / "evil.zip", members={"policy.pth": _torch_payload(marker)}
    )
    with pytest.raises(PolicyFileError, match=r"policy\.pth is not a plain state_dict"):
        load_policy(str(path), _env())
    assert not marker.exists()


def test_cli_refuses_a_malicious_model_in_one_line(
    models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    marker = tmp_path / "pwned"

    def evil(data: dict[str, Any]) -> None:
        data["policy_class"] = _serialized(marker)

    path = _rewrite(models["ppo"], tmp_path / "evil.zip", evil)
    argv = ["evaluate", "--env", ENV_ID, "--policy", str(path), "--episodes", "1"]
    assert main([*argv, "--env-kwargs", json.dumps(ENV_KWARGS)]) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("ias-gym: error: "), err
    assert "--trust-pickle" in lines[0] and "Traceback" not in err
    assert not marker.exists()


def test_trust_pickle_is_sb3s_own_load(models: dict[str, Path], tmp_path: Path) -> None:
    """The opt-in really is SB3's load: a user's own extractor class loads (the safe loader
    refuses it), and a payload in a training-only field does run."""
    with pytest.raises(UntrustedPickleError, match="TinyExtractor"):
        load_policy(str(models["custom"]), _env())
    act = load_policy(str(models["custom"]), _env(), trust_pickle=True)
    assert act.predict(_observations(2)[0])[0].shape == (12,)

    marker = tmp_path / "ran"

    def payload(data: dict[str, Any]) -> None:
        data["lr_schedule"] = _serialized(marker)

    path = _rewrite(models["ppo"], tmp_path / "trusted.zip", payload)
    load_policy(str(path), _env(), trust_pickle=True)
    assert marker.exists()


def test_model_of_another_task_is_refused_before_acting(models: dict[str, Path]) -> None:
    slide = gym.make("IAS-PenSlide-v0")  # 67 observations; the model saw PenRotate's 55
    with pytest.raises(PolicyFileError, match=r"observation_space: shape \(55,\).*another task"):
        load_policy(str(models["ppo"]), slide)


def test_not_a_model_is_a_clear_error(tmp_path: Path) -> None:
    text = tmp_path / "notes.zip"
    text.write_text("not a zip")
    with pytest.raises(PolicyFileError, match="not an SB3 model file"):
        load_policy(str(text), _env())
    with zipfile.ZipFile(tmp_path / "empty.zip", "w") as archive:
        archive.writestr("readme.txt", "hello")
    with pytest.raises(PolicyFileError, match="no 'data' member"):
        load_policy(str(tmp_path / "empty.zip"), _env())
    assert "--trust-pickle" in TRUST_HINT
