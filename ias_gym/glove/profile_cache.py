"""The simulated persons' calibrations, trained once and cached as profiles in the home dir.

``IAS-GloveGrasp-v0`` needs a calibration Θ = f(Ψ) of its simulated person; training the ANN
takes seconds, so :func:`default_calibration` keeps it as a profile (safe JSON, atomic
writes, checked loads: :mod:`ias_gym.glove.profile`) in the user's cache directory.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from tqdm import tqdm

from ias_gym.glove.calibration import ANN_GROUPS, Calibration
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.ids import check_id
from ias_gym.glove.profile import ProfileError, load_profile, save_profile
from ias_gym.settings import seed_from_environment


def cache_dir() -> Path:
    """The profile cache, ``$XDG_CACHE_HOME/ias_gym/glove_profiles`` (``~/.cache/...``),
    created if missing; a directory in the temp dir when the home is read-only."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    path = Path(base) / "ias_gym" / "glove_profiles"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only home: a temp dir
        path = Path(tempfile.gettempdir()) / "ias_gym_glove_profiles"
        path.mkdir(parents=True, exist_ok=True)
    return path


def _fingerprint(person: PersonParams) -> str:
    """A short hash of every parameter of ``person``: a profile trained for other parameters
    of the same id (a changed population, a resized hand) is never taken for theirs."""
    text = json.dumps(person.to_dict(), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:10]


#: Environment variable that trains the cached calibrations under another seed
#: (:func:`calibration_seed`).
CALIBRATION_SEED_VAR = "IAS_GYM_CALIBRATION_SEED"


def calibration_seed() -> int | None:
    """The training seed of :func:`default_calibration`: ``$IAS_GYM_CALIBRATION_SEED`` as an
    integer, None if unset or empty (the default, seed 0).

    Another machine trains a person's calibration to other last bits; another seed trains it
    to another calibration as good as the default one (the same procedure, its own readings
    and initial weights), a check that nothing holds for one trained calibration only.

    Raises:
        InputError: the variable is set but is not an integer >= 0 (a numpy seed).
    """
    return seed_from_environment(CALIBRATION_SEED_VAR)


def default_calibration(person: PersonParams, *, progress: bool = True) -> Calibration:
    """The ANN calibration of a simulated ``person``, trained once and cached as a profile.

    The profile lives in :func:`cache_dir` as ``<person_id>-seed<seed>-<hash>.json`` (the hash
    of the person's parameters); a damaged one is trained again. Training (the first time for
    a person id, any valid id:
    :meth:`~ias_gym.glove.hand.PersonParams.sample`) needs torch (the ``[glove]`` extra) and
    takes seconds; the cached profile then loads in milliseconds.

    With ``$IAS_GYM_CALIBRATION_SEED`` set (:func:`calibration_seed`) the calibration is
    trained under that seed instead of 0 and cached as
    ``<person_id>-seed<seed>-<hash>-calibration<calibration seed>.json``, beside the default one.

    Args:
        person: the simulated person (its id and seed name the file).
        progress: show a progress bar (tqdm, on stderr) while training.

    Raises:
        InputError: the person's id is not a valid id (it names the cache file; see
            :func:`~ias_gym.glove.ids.check_id`), checked before any file is touched.
    """
    person_id = check_id(person.person_id, "person_id")
    training_seed = calibration_seed()
    suffix = "" if training_seed is None else f"-calibration{training_seed}"
    name = f"{person_id}-seed{int(person.seed)}-{_fingerprint(person)}{suffix}.json"
    path = cache_dir() / name
    if path.exists():
        try:
            return load_profile(path, person_id=person.person_id).calibration
        except ProfileError:
            pass  # stale or damaged: train again
    from ias_gym.glove.training import calibrate_person  # torch is optional: on first use only

    # A person never seen before: seconds of training (about 5 s on an idle core, 14 s on a
    # busy one), so say what is happening. Only the shipped ANN is trained: the baselines
    # of `ias-gym calibrate` are not part of the profile.
    with tqdm(
        total=len(ANN_GROUPS),
        desc=f"training the glove calibration of {person.person_id!r} (once; cached)",
        unit="group",
        disable=not progress,
    ) as bar:
        run = calibrate_person(
            person,
            seed=training_seed or 0,
            baselines=False,
            on_group=lambda _name: bar.update(),
        )
    save_profile(run.profile, path)
    return run.profile.calibration
