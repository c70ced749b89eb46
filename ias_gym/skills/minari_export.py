"""Export the demonstrations of a skill database as a Minari dataset (without jax).

Minari's ``DataCollector`` needs jax (``minari[create]``); the dataset is written instead with
``minari.create_dataset_from_buffers`` from one ``EpisodeBuffer`` per skill, which needs only
``minari[hdf5]`` and pillow (the ``[datasets]`` extra; see docs/DESIGN.md, "Demonstrations").
The layout is Minari's: ``T + 1`` observations (reset and final included), ``T`` actions,
rewards, terminations and truncations, and ``T + 1`` rows per info entry. The env spec
(id plus the keyword arguments the skills were recorded with) goes into the dataset, so
``minari.load_dataset(id).recover_environment()`` makes the same env. Datasets are written
under ``MINARI_DATASETS_PATH`` (default ``~/.minari/datasets``).

The database is opened read-only (nothing is created) and every exported skill's arrays
are verified against their checksums as they are loaded. A person id in the env kwargs
must be a valid id (:func:`~ias_gym.glove.ids.check_id`): the recovered env names its
profile file with it (and the env checks it again when a dataset from elsewhere is
recovered).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym

import ias_gym
from ias_gym.glove.ids import check_id
from ias_gym.sim.hands import DEFAULT_HAND, get_hand
from ias_gym.skills.db import SkillDB

#: The install hint of a missing Minari.
INSTALL_HINT = "pip install 'ias-gym[datasets]'"
#: Episodes loaded from the database and written to the dataset at a time.
CHUNK_EPISODES = 16


def _import_minari() -> Any:
    try:
        import minari
        from minari.data_collector.episode_buffer import EpisodeBuffer  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            f"exporting to Minari needs minari[hdf5] and pillow: {INSTALL_HINT} ({exc})"
        ) from exc
    return minari


def export_minari(
    db_path: str | Path,
    dataset_id: str,
    task: str | None = None,
    *,
    success_only: bool = False,
    author: str | None = None,
    description: str | None = None,
) -> Path:
    """Write the stored demonstrations of one task as a Minari dataset.

    Args:
        db_path: the skill database.
        dataset_id: Minari id, ``(namespace/)name-v<version>``, e.g. ``"ias/pen-rotate-expert-v0"``.
        task: export only this env id's skills; required when the database holds several
            tasks (or one task recorded with different env settings).
        success_only: export only skills whose episode succeeded.
        author: dataset author (default: the skills' person ids, else ``"ias-gym"``).
        description: dataset description (default: generated from the skills).

    Returns:
        The dataset's directory.

    Raises:
        ImportError: minari is not installed (the message says which extra to install).
        ValueError: no skills match, or they come from different envs or env settings.
        InputError: the env kwargs hold an invalid ``person_id``.
        FileExistsError: a dataset with this id exists already.
        SkillDBError: the database is missing, empty or not one, or a skill's arrays do
            not match their checksums (nothing is left of the dataset then).
    """
    # minari is the optional [datasets] extra: imported only when exporting
    minari = _import_minari()
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.storage import get_dataset_path

    with SkillDB(db_path, readonly=True) as db:
        summaries = db.list_skills(task=task, success=True if success_only else None)
        if not summaries:
            which = f" of task {task!r}" if task else ""
            which += " that succeeded" if success_only else ""
            raise ValueError(
                f"no skills{which} in {db_path} (tasks there: {db.tasks()}); record some "
                "with `ias-gym skills record`"
            )
        envs = sorted({(s.task, json.dumps(s.env_kwargs, sort_keys=True)) for s in summaries})
        if len(envs) > 1:
            raise ValueError(
                f"a Minari dataset holds one environment, but the skills come from {envs} "
                "(task, env kwargs); pass task= (--task) to choose one"
            )
        task_id, env_kwargs = summaries[0].task, summaries[0].env_kwargs
        if "person_id" in env_kwargs:
            check_id(env_kwargs["person_id"], "the skills' env kwargs person_id")
        try:
            registered = gym.spec(task_id)
        except gym.error.Error as exc:
            raise ValueError(
                f"the skills' task {task_id!r} is not a registered Gymnasium id ({exc}); "
                "import the package that registers it"
            ) from exc
        env_spec = dataclasses.replace(registered, kwargs={**registered.kwargs, **env_kwargs})
        sources = sorted({s.source for s in summaries})
        people = sorted({s.person_id for s in summaries if s.person_id})
        path = Path(get_dataset_path(dataset_id))
        if path.exists():
            raise FileExistsError(
                f"a Minari dataset {dataset_id!r} exists already at {path}; choose another id "
                "(or version) or delete it"
            )

        def buffers(start: int) -> list[Any]:
            out = []
            for index in range(start, min(start + CHUNK_EPISODES, len(summaries))):
                summary = summaries[index]
                demo = db.get(summary.id).demonstration
                out.append(
                    EpisodeBuffer(
                        id=index,
                        seed=summary.seed,
                        observations=demo.observations,
                        actions=demo.actions,
                        rewards=demo.rewards,
                        terminations=demo.terminations,
                        truncations=demo.truncations,
                        infos=dict(demo.infos),
                    )
                )
            return out

        try:
            with warnings.catch_warnings():
                # Minari warns about every metadata field left None; a permalink and an
                # email are not known here.
                warnings.filterwarnings("ignore", message=r"`(code_permalink|author_email)` is")
                dataset = minari.create_dataset_from_buffers(
                    dataset_id=dataset_id,
                    buffer=buffers(0),
                    env=env_spec,
                    eval_env=env_spec,
                    algorithm_name=", ".join(sources),
                    author=author or (", ".join(people) if people else "ias-gym"),
                    description=description
                    or (
                        f"{len(summaries)} demonstrations of {task_id} (env kwargs "
                        f"{env_kwargs}) from {', '.join(sources)}, exported from the ias-gym "
                        f"skill database {Path(db_path).name}"
                    ),
                    requirements=[f"ias-gym>={ias_gym.__version__}"],
                    data_format="hdf5",
                )
            # The rest in chunks, so memory holds a few episodes, not the whole database.
            for start in range(CHUNK_EPISODES, len(summaries), CHUNK_EPISODES):
                dataset.update_dataset_from_buffer(buffers(start))
        except BaseException:
            shutil.rmtree(path, ignore_errors=True)  # no half-written dataset left behind
            raise
    return path


#: The Minari id of the robot executions of the shipped human skills on the default hand
#: (the counterpart of D4RL's/Minari's Adroit ``pen-human`` dataset).
PEN_SKILL_DATASET_ID = "ias/pen-skill/human-v0"


def pen_skill_dataset_id(hand: str = DEFAULT_HAND) -> str:
    """The Minari id of the executions on ``hand``: :data:`PEN_SKILL_DATASET_ID` on the
    default hand, ``ias/pen-skill-<hand>/human-v0`` on another (one dataset per hand: their
    observation and action spaces differ).

    Raises:
        InputError: an unknown hand (the message lists the known ones).
    """
    get_hand(hand)
    return PEN_SKILL_DATASET_ID if hand == DEFAULT_HAND else f"ias/pen-skill-{hand}/human-v0"


def pen_skill_dataset_exists(dataset_id: str) -> bool:
    """Whether a Minari dataset of that id is stored already (``MINARI_DATASETS_PATH``).

    Raises:
        ImportError: minari is not installed (the message names the extra).
    """
    _import_minari()
    from minari.storage import get_dataset_path

    return Path(get_dataset_path(dataset_id)).exists()


def export_pen_skill_dataset(
    dataset_id: str | None = None,
    hand: str = DEFAULT_HAND,
    episodes_per_skill: int = 1,
    db_path: str | Path | None = None,
    skill_ids: list[int] | None = None,
) -> Path:
    """Record the expert executing every human skill on ``IAS-PenSkill-v0`` and export it.

    Each episode is the grip-transform expert (Theorem 1 with the skill's grasp margin)
    executing one skill of the shipped human-skill library on ``hand``; the seeds are chosen
    so that every skill is executed ``episodes_per_skill`` times (the env draws its skill from
    the seed, so ``recover_environment()`` and ``reset(seed=...)`` replay the same skill). The
    infos carry the forces: ``contact_forces`` (k x 3 [N], each fingertip's intensities
    normal, t1, t2), ``internal_forces`` (the measured ``c_h`` [N]), the grasp ``margin`` and
    its reference, and the tracking errors.

    Args:
        dataset_id: the Minari id (default: :func:`pen_skill_dataset_id` of the hand).
        hand: the robot hand (``ias_gym.sim.hands``).
        episodes_per_skill: executions of every skill (>= 1).
        db_path: keep the recorded executions in this new skill database (default: a
            temporary one, removed afterwards).
        skill_ids: only these skills of the library (default: all); stored in the
            dataset's env kwargs.

    Returns:
        The dataset's directory.

    Raises:
        ImportError: minari is not installed.
        FileExistsError: the dataset or ``db_path`` exists already.
        ValueError: ``episodes_per_skill`` < 1.
    """
    import tempfile

    from ias_gym.baselines.expert import ExpertPolicy
    from ias_gym.skills.record import record_episode
    from ias_gym.skills.transfer_run import transfer_gains

    if episodes_per_skill < 1:
        raise ValueError(f"episodes_per_skill must be >= 1, got {episodes_per_skill}")
    if dataset_id is None:
        dataset_id = pen_skill_dataset_id(hand)
    # before the work: a missing extra must not cost the recording
    if pen_skill_dataset_exists(dataset_id):
        raise FileExistsError(f"a Minari dataset {dataset_id!r} exists already")
    if db_path is not None and Path(db_path).exists():
        raise FileExistsError(f"{db_path} exists already; give a new file")
    env_kwargs: dict[str, Any] = {"hand": hand}
    if skill_ids is not None:
        env_kwargs["skill_ids"] = [int(i) for i in skill_ids]
    env = gym.make("IAS-PenSkill-v0", **env_kwargs)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(db_path) if db_path is not None else Path(tmp) / "executions.db"
        try:
            unwrapped: Any = env.unwrapped
            n_skills = len(unwrapped.references)
            wanted = dict.fromkeys(range(n_skills), episodes_per_skill)
            expert = ExpertPolicy(env, transfer_gains(hand))  # as `skills transfer` runs it
            seed = 0
            with SkillDB(path) as db:
                while any(wanted.values()):
                    _, info = env.reset(seed=seed)
                    index = int(info["skill_index"])
                    if wanted[index]:
                        reference = unwrapped.references[index]
                        skill = record_episode(
                            env,
                            expert,
                            seed=seed,
                            source="expert",
                            name=f"{reference.name} of {reference.person} on {hand}",
                            person_id=reference.person or None,
                            env_kwargs=env_kwargs,
                        )
                        db.add(skill)
                        wanted[index] -= 1
                    seed += 1
        finally:
            env.close()
        return export_minari(
            path,
            dataset_id,
            "IAS-PenSkill-v0",
            author="ias-gym (expert executing human glove skills)",
            description=(
                f"The grip-transform expert (Theorem 1) on hand {hand} executing each human "
                f"skill of the ias-gym library {episodes_per_skill} time(s): the pen's motion "
                "relative to the person's grasp, scaled into the hand's workspace, held with "
                "the person's grasp margin. Infos carry the contact forces and the internal "
                "forces (c_h) per step."
            ),
        )
