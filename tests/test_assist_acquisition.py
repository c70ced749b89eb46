"""The loop closed (ias_gym.assist.policy.ObservationAssistant.learn): a skill the library
lacks is not completed; demonstrated in acquisition mode it is stored and, from the next
session on, recognised and completed for a stopped operator like a shipped skill."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401
from ias_gym.assist.pad_contact import PinchClosing, pinch_closing
from ias_gym.assist.policy import AssistParams, ObservationAssistant, make_assistant
from ias_gym.assist.recognition import UNKNOWN
from ias_gym.assist.skill_motions import shrunk_spread
from ias_gym.assist.stream import record_session
from ias_gym.cli import main
from ias_gym.errors import InputError
from ias_gym.glove.hand import joint_index
from ias_gym.glove.population import population_ids
from ias_gym.perturbed_starts import perturbed_starts
from ias_gym.skills import SkillDB
from ias_gym.skills.transfer import shipped_skill_db

PRON = joint_index("wrist_pronation")
NEW = "tilt_left"
NAME = "my_tilt"
#: A stop detector that latches (as in tests/test_assist_policy.py): these tests are about
#: what is completed, not about the fitted threshold's rates (the tremor canceller, which
#: touches every joint a little, is off).
LATCHING = AssistParams(stop_window_s=0.1, stop_ratio=0.3)


def _library_without(tmp_path: Path, skill: str) -> Path:
    path = tmp_path / "library.db"
    shutil.copyfile(shipped_skill_db(), path)
    with SkillDB(path) as db:
        for skill_id in db.ids():
            if db.get(skill_id).name == skill:
                db.delete(skill_id)
    return path


def _stopped_sessions(assistant: ObservationAssistant) -> list[tuple[np.ndarray, np.ndarray]]:
    """(operator's, commanded) pronation of a stopped tilt_left from reset seed 0 and from
    its nearby starts, the assistant fed the observations."""
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", skill=NEW, impairment="stops:at=0.4")
    layout = dict(env.unwrapped.observation_layout)  # type: ignore[attr-defined]
    scale = env.unwrapped.config.action_scale  # type: ignore[attr-defined]
    out = []
    for options in list(perturbed_starts(env, 0)):
        assistant.reset()
        obs, _ = env.reset(seed=0, options=options)
        op, cmd = [], []
        done = False
        while not done:
            action = assistant.act(obs.copy(), layout)
            op.append(obs[layout["upcoming_theta"]][PRON])
            cmd.append(op[-1] + scale * action[PRON])
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
        out.append((np.array(op), np.array(cmd)))
    env.close()
    return out


@pytest.fixture(scope="module")
def acquired(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The shipped library without tilt_left, its assistant before and after learning it
    from population persons' demonstrations (until two are stored)."""
    path = _library_without(tmp_path_factory.mktemp("acq"), NEW)
    assistant = make_assistant(path, recogniser="phase", params=LATCHING, tremor=False)
    assert assistant.pads is not None
    closing_before = assistant.pads.closing
    before = _stopped_sessions(assistant)
    results = []
    with SkillDB(path) as db:
        for person in population_ids(8, 0):
            env = gym.make("IAS-GloveGrasp-v0", person_id=person, skill=NEW)
            skill, frames = record_session(env, seed=0)
            env.close()
            if skill.is_success:
                results.append(assistant.learn(db, skill, frames, NAME))
            if sum(r.stored_as == NAME for r in results) == 2:
                break
        names = [db.get(i).name for i in db.ids()]
    return {
        "assistant": assistant,
        "before": before,
        "results": results,
        "names": names,
        "path": path,
        "closing_before": closing_before,
    }


def test_a_skill_the_library_lacks_is_not_completed(acquired: dict[str, object]) -> None:
    for op, cmd in acquired["before"]:  # type: ignore[attr-defined]
        # the hand is not turned on the way tilt_left turns (another skill latched in its
        # place may hold the pen's tilt, which turns it back, if at all)
        assert (cmd[0] - cmd[-1]) < (op[0] - op[-1]) + 0.01


def test_an_unknown_demonstration_is_stored_and_learnt(acquired: dict[str, object]) -> None:
    results = acquired["results"]
    assistant = acquired["assistant"]
    assert isinstance(assistant, ObservationAssistant)
    assert results[0].recognised == UNKNOWN  # type: ignore[index]
    assert results[0].stored_as == NAME  # type: ignore[index]
    assert acquired["names"].count(NAME) == 2  # type: ignore[attr-defined]
    assert NAME in assistant.motions and PRON in assistant.motions[NAME].joints
    assert NAME in assistant.recogniser.skills


def _same_closing(a: PinchClosing, b: PinchClosing) -> bool:
    return (a.meet_s, a.touch_from_s) == (b.meet_s, b.touch_from_s) and all(
        np.allclose(a.directions[f], b.directions[f]) for f in a.directions
    )


def test_the_pad_keeping_reads_the_acquired_pinches(acquired: dict[str, object]) -> None:
    assistant = acquired["assistant"]
    assert isinstance(assistant, ObservationAssistant) and assistant.pads is not None
    now = pinch_closing(acquired["path"])  # type: ignore[arg-type]
    # the stored demonstrations moved the library's pinch, and the assistant follows it
    assert not _same_closing(now, acquired["closing_before"])  # type: ignore[arg-type]
    assert _same_closing(assistant.pads.closing, now)


def test_the_acquired_skill_is_completed_for_a_stopped_operator(
    acquired: dict[str, object],
) -> None:
    assistant = acquired["assistant"]
    assert isinstance(assistant, ObservationAssistant)
    for op, cmd in _stopped_sessions(assistant):
        assert assistant.completing == NAME
        # the hand turns on the way tilt_left turns, well beyond where the operator stopped
        # (the pen then held at the tilt the demonstrations give this operator)
        assert (cmd[0] - cmd[-1]) > (op[0] - op[-1]) + 0.025


def test_learning_needs_the_assistants_own_library_and_skill_knowledge(tmp_path: Path) -> None:
    path = _library_without(tmp_path, NEW)
    other = tmp_path / "other.db"
    shutil.copyfile(path, other)
    with SkillDB(other) as db:
        skill = db.get(db.ids()[0])
        frames: list = []
        with pytest.raises(InputError, match="own library"):
            make_assistant(path, recogniser="phase").learn(db, skill, frames, NAME)
    with SkillDB(path) as db, pytest.raises(InputError, match="skill knowledge"):
        make_assistant(path, recogniser="none").learn(db, skill, frames, NAME)


def test_one_demonstration_borrows_the_pooled_spread() -> None:
    assert shrunk_spread(np.array([1.3]), 0.07) == pytest.approx(0.07)
    many = np.random.default_rng(0).normal(1.0, 0.1, 400)
    assert shrunk_spread(many, 0.5) == pytest.approx(float(np.std(many)), rel=0.05)
    # between: never below the sample's own spread
    few = np.array([0.9, 1.1])
    assert float(np.std(few)) < shrunk_spread(few, 0.2) < 0.2


def test_cli_acquire(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _library_without(tmp_path, NEW)
    args = ["assist", "acquire", "--db", str(path), "--skill", NEW, "--json"]
    assert main([*args, "--person", "p1", "--name", NAME]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["recognised"] == UNKNOWN and out["stored_as"] == NAME
    with SkillDB(path, readonly=True) as db:
        assert db.get(out["skill_id"]).name == NAME
    for bad, match in (
        (["--person", "p1", "--name", UNKNOWN], "--name"),
        (["--person", "", "--name", NAME], "--person"),
        (["--person", "p1", "--name", NAME, "--skill", "tilt"], "--skill"),
    ):
        assert main([*args, *bad]) == 2
        err = capsys.readouterr().err
        assert match in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    with SkillDB(path, readonly=True) as db:
        assert [db.get(i).name for i in db.ids()].count(NAME) == 1  # nothing more stored
