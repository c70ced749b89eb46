"""Loading a saved Stable-Baselines3 model (``.zip``) without running code from the file.

SB3's ``load`` unpickles (cloudpickle) every attribute it could not store as JSON: the
policy class, the spaces, ``policy_kwargs`` holding a class, the learning-rate schedule...
A pickle can run any code when it is loaded, so opening a model file from elsewhere with
``PPO.load`` is running a program from elsewhere. This module rebuilds what *acting* needs
from the JSON alone:

* the zip's ``data`` member is JSON; SB3 writes a pickled attribute as
  ``{":type:": "<class ...>", ":serialized:": base64 pickle, <its first-level fields as
  JSON or as str()>}`` (``stable_baselines3.common.save_util.data_to_json``). Only those
  JSON descriptions are read, never the ``:serialized:`` payloads;
* the policy class comes from its ``__module__`` and the qualified names of its methods,
  and must be one of SB3's own (:data:`POLICY_CLASSES`); the algorithm from the fields
  only it has (``clip_range`` is PPO's, ``target_entropy`` SAC's, ...);
* the spaces are the env's, checked against the file's description (type, shape, dtype,
  bounds), so a model of another task is refused before it acts;
* ``policy_kwargs``: JSON values as they are; a class (``activation_fn``,
  ``features_extractor_class``, ``optimizer_class``) only if its name is on an allow-list
  (torch activations and optimisers, SB3's extractors,
  :class:`~ias_gym.learning.normalisation.ObservationNormalizer`, also by its old path);
* the weights: ``policy.pth`` with ``torch.load(..., weights_only=True)``. The optimiser
  states, ``pytorch_variables.pth`` and the training-only fields (schedules, buffers) are
  not read at all: acting does not need them.

A file whose needed fields exist only as pickles is refused with a message naming the
opt-in (``--trust-pickle`` / ``trust_pickle=True``), which falls back to SB3's ``load``.
"""

from __future__ import annotations

import importlib
import json
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError, PolicyFileError, UntrustedPickleError  # noqa: F401 - defined there, raised here

#: The SB3 algorithms a file may hold, in the order tried when the JSON does not say.
ALGORITHMS = ("PPO", "SAC", "TD3", "A2C", "DDPG")
#: Policy classes rebuilt from their name: SB3's own, per module.
POLICY_CLASSES: Mapping[str, frozenset[str]] = {
    "stable_baselines3.common.policies": frozenset(
        {"ActorCriticPolicy", "ActorCriticCnnPolicy", "MultiInputActorCriticPolicy"}
    ),
    "stable_baselines3.sac.policies": frozenset({"SACPolicy", "CnnPolicy", "MultiInputPolicy"}),
    "stable_baselines3.td3.policies": frozenset({"TD3Policy", "CnnPolicy", "MultiInputPolicy"}),
}
#: Features extractors rebuilt from their name: the (module, class) a file names -> the
#: (module, class) built for it.
FEATURES_EXTRACTORS: Mapping[tuple[str, str], tuple[str, str]] = {
    **{
        (module, name): (module, name)
        for module, name in (
            ("stable_baselines3.common.torch_layers", "FlattenExtractor"),
            ("stable_baselines3.common.torch_layers", "NatureCNN"),
            ("stable_baselines3.common.torch_layers", "CombinedExtractor"),
            ("ias_gym.learning.normalisation", "ObservationNormalizer"),
        )
    },
    # Models saved before the normaliser moved out of ias_gym.baselines.bc (removed) name
    # it there.
    ("ias_gym.baselines.bc", "ObservationNormalizer"): (
        "ias_gym.learning.normalisation",
        "ObservationNormalizer",
    ),
}
#: Largest ``data`` member read [bytes]: SB3 writes a few kB; a bigger one is not a model.
MAX_DATA_BYTES = 64 * 2**20
TRUST_HINT = (
    "loading it would run code stored in the file. Only if you trust the file, pass "
    "--trust-pickle (ias-gym) / trust_pickle=True (library) to load it with SB3's own load"
)

_CLASS_REPR = re.compile(r"<class '([A-Za-z_][\w.]*)'>")
_METHOD_REPR = re.compile(r"<function ([A-Za-z_][\w.]*)\.[A-Za-z_]\w* at 0x[0-9a-fA-F]+>")


@dataclass(frozen=True)
class LoadedPolicy:
    """An SB3 policy loaded from a file, callable as ``obs -> action`` (deterministic).

    Attributes:
        algorithm: ``"PPO"``, ``"SAC"``, ... as read from the file.
        policy: the SB3 policy (a ``torch.nn.Module`` on the CPU, in evaluation mode).
    """

    algorithm: str
    policy: Any

    def __call__(self, obs: NDArray[Any]) -> NDArray[Any]:
        """The deterministic action for ``obs``, as ``model.predict(obs, deterministic=True)``."""
        action, _ = self.policy.predict(obs, deterministic=True)
        return np.asarray(action)


def _refuse(path: Path, field: str, why: str) -> UntrustedPickleError:
    return UntrustedPickleError(f"{path}: {field} {why}; {TRUST_HINT}")


def read_model_json(path: Path | str) -> dict[str, Any]:
    """The ``data`` JSON of an SB3 ``.zip`` (pickled fields left as their JSON description).

    Args:
        path: the model file.

    Raises:
        PolicyFileError: not a zip, no ``data`` member, too big, or not a JSON object.
    """
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            try:
                info = archive.getinfo("data")
            except KeyError:
                raise PolicyFileError(
                    f"{path} is not an SB3 model: the zip has no 'data' member"
                ) from None
            if info.file_size > MAX_DATA_BYTES:
                raise PolicyFileError(
                    f"{path}: its 'data' member has {info.file_size} bytes, more than an SB3 "
                    f"model's ({MAX_DATA_BYTES} at most)"
                )
            text = archive.read(info).decode("utf-8")
    except (zipfile.BadZipFile, UnicodeDecodeError) as exc:
        raise PolicyFileError(f"{path} is not an SB3 model file (.zip): {exc}") from None
    except OSError as exc:
        raise PolicyFileError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PolicyFileError(f"{path}: its 'data' member is not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise PolicyFileError(f"{path}: its 'data' member is not a JSON object")
    return data


def _is_pickled(item: Any) -> bool:
    return isinstance(item, dict) and ":serialized:" in item


def _policy_class_name(path: Path, data: Mapping[str, Any]) -> tuple[str, str]:
    """(module, class name) of the policy from the JSON description of its pickled class."""
    item = data.get("policy_class")
    if item is None:
        raise PolicyFileError(f"{path} is not an SB3 model: its data has no policy_class")
    if not _is_pickled(item):
        raise PolicyFileError(f"{path}: policy_class is not a class description: {item!r}")
    module = item.get("__module__")
    # The class's own methods are listed as "<function Class.method at 0x...>".
    owners = {
        m.group(1)
        for value in item.values()
        if isinstance(value, str) and (m := _METHOD_REPR.fullmatch(value))
    }
    if not isinstance(module, str) or len(owners) != 1:
        raise _refuse(path, "policy_class", "is stored only as a pickle (no class name in JSON)")
    name = owners.pop()
    if name not in POLICY_CLASSES.get(module, ()):
        raise _refuse(
            path,
            f"policy_class {module}.{name}",
            "is not one of SB3's policies that can be rebuilt without unpickling",
        )
    return module, name


def algorithm_of(data: Mapping[str, Any], policy_module: str | None = None) -> str | None:
    """The SB3 algorithm that wrote ``data`` (the ``data`` JSON of a model), from the
    fields only that algorithm saves; ``None`` if they do not tell."""
    if policy_module is None:
        item = data.get("policy_class")
        policy_module = item.get("__module__") if isinstance(item, dict) else None
    if policy_module == "stable_baselines3.common.policies":
        return "PPO" if "clip_range" in data else "A2C" if "normalize_advantage" in data else None
    if policy_module == "stable_baselines3.sac.policies" or "target_entropy" in data:
        return "SAC"
    if policy_module == "stable_baselines3.td3.policies" or "policy_delay" in data:
        # DDPG is TD3 with one critic update per actor update and no target smoothing.
        ddpg = data.get("policy_delay") == 1 and data.get("target_noise_clip") == 0.0
        return "DDPG" if ddpg else "TD3"
    return None


def _resolve_class(path: Path, key: str, text: str) -> type:
    """The class ``text`` (``"<class 'module.Name'>"``) names, if ``key`` may hold it."""
    match = _CLASS_REPR.fullmatch(text)
    if match is None:
        raise _refuse(path, f"policy_kwargs[{key!r}]", "is stored only as a pickle")
    module, _, name = match.group(1).rpartition(".")
    if key == "activation_fn":
        allowed = module == "torch.nn.modules.activation"
    elif key == "optimizer_class":
        allowed = module.startswith("torch.optim.")
    elif key == "features_extractor_class":
        allowed = (module, name) in FEATURES_EXTRACTORS
        if allowed:
            module, name = FEATURES_EXTRACTORS[module, name]
    else:
        allowed = False
    if not allowed:
        raise _refuse(
            path,
            f"policy_kwargs[{key!r}] = {module}.{name}",
            "is not a class that can be rebuilt by name",
        )
    # Only allow-listed modules are imported: torch's own and the extractors above.
    value = getattr(importlib.import_module(module), name, None)
    if not isinstance(value, type):
        raise PolicyFileError(f"{path}: policy_kwargs[{key!r}] names {module}.{name}, not found")
    return value


def _policy_kwargs(path: Path, data: Mapping[str, Any]) -> dict[str, Any]:
    """``policy_kwargs`` from JSON: plain values kept, allow-listed classes by name."""
    item = data.get("policy_kwargs", {})
    if not _is_pickled(item):
        if not isinstance(item, dict):
            raise PolicyFileError(f"{path}: policy_kwargs is not a JSON object: {item!r}")
        kwargs = dict(item)
    else:
        if item.get(":type:") != "<class 'dict'>":
            raise _refuse(path, "policy_kwargs", "is stored only as a pickle (not a dict)")
        kwargs = {}
        for key, value in item.items():
            if key.startswith(":"):
                continue
            # data_to_json keeps JSON-serialisable items and stores str() of the others; a
            # string is therefore a class (resolved by name) or an object we cannot rebuild.
            kwargs[key] = _resolve_class(path, key, value) if isinstance(value, str) else value
    kwargs.pop("device", None)  # SB3's load drops it too
    net_arch = kwargs.get("net_arch")
    if isinstance(net_arch, list) and net_arch and isinstance(net_arch[0], dict):
        kwargs["net_arch"] = net_arch[0]  # the pre-1.8 format, converted as SB3's load does
    return kwargs


def _parse_bounds(text: Any, shape: tuple[int, ...]) -> NDArray[np.float64] | None:
    """A Box bound from its str() (``"[-1. -1.]"``), or None if numpy summarised it."""
    if not isinstance(text, str) or "..." in text:
        return None
    try:
        values = np.array([float(v) for v in text.replace("[", " ").replace("]", " ").split()])
    except ValueError:
        return None
    return values.reshape(shape) if values.size == int(np.prod(shape)) else None


def _check_space(path: Path, field: str, item: Any, space: gym.Space[Any]) -> None:
    """Refuse the file if its JSON description of ``field`` does not match ``space``."""
    if not isinstance(item, dict):
        raise PolicyFileError(f"{path}: {field} is missing or not a space description")
    cls = type(space)
    expected = f"<class '{cls.__module__}.{cls.__qualname__}'>"
    saved_shape = item.get("_shape")
    mismatch = []
    if item.get(":type:") != expected:
        mismatch.append(f"type {item.get(':type:')}")
    if saved_shape is not None and tuple(saved_shape) != space.shape:
        mismatch.append(f"shape {tuple(saved_shape)}")
    if item.get("dtype") is not None and item.get("dtype") != str(space.dtype):
        mismatch.append(f"dtype {item.get('dtype')}")
    if not mismatch and isinstance(space, gym.spaces.Box):
        for bound, ours in (("low", space.low), ("high", space.high)):
            saved = _parse_bounds(item.get(bound), space.shape)
            # str() prints 8 significant digits: equal to that precision.
            if saved is not None and not np.allclose(saved, ours, rtol=1e-6, atol=0.0):
                mismatch.append(f"{bound} {item.get(bound)}")
    if mismatch:
        raise PolicyFileError(
            f"{path} was saved for another {field}: {', '.join(mismatch)}, but the env has "
            f"{space}; is it a model of another task?"
        )


def _check_loaded_spaces(path: Path, model: Any, env: gym.Env[Any, Any]) -> None:
    for field in ("observation_space", "action_space"):
        saved, ours = getattr(model, field), getattr(env, field)
        if saved.shape != ours.shape or saved.dtype != ours.dtype:
            raise PolicyFileError(
                f"{path} was saved for another {field}: {saved}, but the env has "
                f"{ours}; is it a model of another task?"
            )


def _moved_classes(path: Path, data: Mapping[str, Any]) -> dict[str, Any] | None:
    """``custom_objects`` for SB3's load if ``policy_kwargs`` names a class that has moved.

    Its pickle refers to the old module, which no longer exists: ``policy_kwargs`` is then
    rebuilt from the JSON instead (the other fields are still unpickled).
    """
    item = data.get("policy_kwargs")
    if not isinstance(item, dict) or not _is_pickled(item):
        return None
    for value in item.values():
        match = _CLASS_REPR.fullmatch(value) if isinstance(value, str) else None
        if match is None:
            continue
        module, _, name = match.group(1).rpartition(".")
        if FEATURES_EXTRACTORS.get((module, name), (module, name)) != (module, name):
            try:
                return {"policy_kwargs": _policy_kwargs(path, data)}
            except UntrustedPickleError:  # another class not known by name: only the pickle
                return None
    return None


def _load_with_pickle(path: Path, data: Mapping[str, Any], env: gym.Env[Any, Any]) -> Any:
    """SB3's own load (it unpickles the file): the algorithm from the JSON, or each in turn."""
    import stable_baselines3

    known = algorithm_of(data)
    custom_objects = _moved_classes(path, data)
    errors = []
    for name in (known,) if known else ALGORITHMS:
        try:
            model = getattr(stable_baselines3, name).load(
                path, device="cpu", custom_objects=custom_objects
            )
        except Exception as exc:  # each algorithm refuses another's file differently
            errors.append(f"{name}: {type(exc).__name__}: {exc}")
            continue
        _check_loaded_spaces(path, model, env)
        return LoadedPolicy(name, model.policy)
    raise PolicyFileError(f"{path} is not a model of {known or ALGORITHMS}: {'; '.join(errors)}")


def load_sb3_policy(
    path: Path | str, env: gym.Env[Any, Any], *, trust_pickle: bool = False
) -> LoadedPolicy:
    """Load the policy of a saved SB3 model for acting in ``env``, without unpickling.

    Args:
        path: the model file (``model.save(path)``).
        env: the env it will act in; its spaces are the policy's, checked against the file.
        trust_pickle: use SB3's own ``load``, which unpickles the file's fields (runs code
            from the file: only for files you trust).

    Returns:
        The policy, callable ``obs -> action`` (deterministic).

    Raises:
        UntrustedPickleError: a field acting needs exists only as a pickle (the message
            names the opt-in).
        PolicyFileError: not an SB3 model, saved for other spaces, or weights that do not
            fit the policy the file describes.
        ImportError: stable-baselines3 is not installed.
    """
    path = Path(path)
    data = read_model_json(path)
    if trust_pickle:
        return _load_with_pickle(path, data, env)

    import torch

    module, name = _policy_class_name(path, data)
    algorithm = algorithm_of(data, module)
    if algorithm is None:
        raise PolicyFileError(f"{path}: cannot tell which SB3 algorithm saved it")
    policy_class = getattr(importlib.import_module(module), name)
    _check_space(path, "observation_space", data.get("observation_space"), env.observation_space)
    _check_space(path, "action_space", data.get("action_space"), env.action_space)
    kwargs = _policy_kwargs(path, data)
    if module == "stable_baselines3.common.policies":
        # On-policy algorithms pass use_sde themselves (off-policy ones store it in kwargs).
        kwargs.setdefault("use_sde", bool(data.get("use_sde", False)))
    # The learning rate only sizes the optimiser, which acting never steps.
    learning_rate = data.get("learning_rate")
    lr = float(learning_rate) if isinstance(learning_rate, (int, float)) else 0.0
    try:
        policy = policy_class(
            env.observation_space, env.action_space, lambda _progress: lr, **kwargs
        )
    except (TypeError, ValueError, RuntimeError) as exc:
        raise PolicyFileError(
            f"{path}: cannot build its {name} from policy_kwargs {sorted(kwargs)}: {exc}"
        ) from None
    try:
        with zipfile.ZipFile(path) as archive, archive.open("policy.pth") as weights:
            state = torch.load(weights, map_location="cpu", weights_only=True)
    except KeyError:
        raise PolicyFileError(f"{path} has no policy.pth (the policy's weights)") from None
    except Exception as exc:  # torch raises UnpicklingError/RuntimeError/... for non-tensors
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise PolicyFileError(
            f"{path}: policy.pth is not a plain state_dict of tensors ({first})"
        ) from None
    try:
        policy.load_state_dict(state)
    except (RuntimeError, TypeError, AttributeError) as exc:
        raise PolicyFileError(
            f"{path}: the weights in policy.pth do not fit the {name} its data describes: "
            f"{' '.join(str(exc).split())}"
        ) from None
    policy.set_training_mode(False)
    return LoadedPolicy(algorithm, policy)


__all__ = [
    "ALGORITHMS",
    "FEATURES_EXTRACTORS",
    "POLICY_CLASSES",
    "TRUST_HINT",
    "LoadedPolicy",
    "PolicyFileError",
    "UntrustedPickleError",
    "algorithm_of",
    "load_sb3_policy",
    "read_model_json",
]
