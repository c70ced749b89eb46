"""Evaluation, disturbance sweeps and skill recording on worker processes and on Ray: the
same results as the serial run bit for bit, faults retried once and then named, options
checked before any work."""

from __future__ import annotations

import json
import os
import signal
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ias_gym.cli import main
from ias_gym.runtime.jobs import (
    RAY_MISSING,
    Backend,
    WorkerError,
    iter_jobs,
    run_jobs,
)
from ias_gym.skills.db import DEMO_ARRAYS, MODEL_ARRAYS, SkillDB

#: Short PenRotate episodes (1 s settling + 0.2 s tracked) [s]: the expert's controller and
#: the disturbances act, and 8 of them take a few seconds.
SHORT = {"duration": 1.2}
EVALUATE = ["evaluate", "--env", "IAS-PenRotate-v0", "--episodes", "8", "--seed", "3", "--json"]
EVALUATE += ["--env-kwargs", json.dumps(SHORT)]
#: Recorded episodes: 0.3 s of PenRotate, tracking judged from 0.2 s on [s].
RECORD_KWARGS = {"duration": 0.3, "settle_time": 0.2}

try:
    import ray  # noqa: F401

    HAVE_RAY = True
except ImportError:
    HAVE_RAY = False
needs_ray = pytest.mark.skipif(
    not HAVE_RAY, reason="ray is not installed (the [distributed] extra; make test installs it)"
)


@dataclass(frozen=True)
class Killer:
    """A job that kills its own worker process (SIGKILL: no cleanup, no exception) when it
    runs ``victim``: only the first time (``always=False``, a marker file remembers it
    across processes) or every time."""

    marker_dir: str
    victim: int
    always: bool = False

    def __call__(self, item: int) -> tuple[int, int]:
        if item == self.victim:
            marker = Path(self.marker_dir) / f"killed-{item}"
            if self.always or not marker.exists():
                marker.touch()
                os.kill(os.getpid(), signal.SIGKILL)
        return item * item, os.getpid()


@dataclass(frozen=True)
class TorchThreads:
    """A job that reports the size of torch's thread pool in the process running it."""

    def __call__(self, item: int) -> int:
        import torch

        return int(torch.get_num_threads())


def _json_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


# ---------------------------------------------------------------- same results everywhere
def test_evaluate_json_is_the_same_on_1_and_2_workers(capsys: pytest.CaptureFixture[str]) -> None:
    serial = _json_line([*EVALUATE, "--workers", "1"], capsys)
    pool = _json_line([*EVALUATE, "--workers", "2"], capsys)
    assert serial["episodes"] == 8 and serial["success_rate"] > 0
    assert json.dumps(pool) == json.dumps(serial)  # every float bit for bit, keys in order


@needs_ray
def test_evaluate_json_is_the_same_on_a_local_ray(capsys: pytest.CaptureFixture[str]) -> None:
    import ray

    assert not ray.is_initialized()
    serial = _json_line(EVALUATE, capsys)
    on_ray = _json_line([*EVALUATE, "--ray"], capsys)
    assert json.dumps(on_ray) == json.dumps(serial)
    assert not ray.is_initialized()  # the local Ray started for the run is shut down


def test_the_video_episode_rendered_here_is_the_workers_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With --video the first episode runs here in a rendering env, the others on workers:
    the summary is still the serial one without a video."""
    argv = [*EVALUATE[:4], "3", *EVALUATE[5:]]  # 3 episodes
    serial = _json_line(argv, capsys)
    video = tmp_path / "first.mp4"
    with_video = _json_line([*argv, "--workers", "2", "--video", str(video)], capsys)
    assert with_video.pop("video") == str(video) and video.stat().st_size > 0
    assert json.dumps(with_video) == json.dumps(serial)


def test_random_policy_episodes_depend_on_their_seed_alone() -> None:
    """The random policy's actions are seeded per episode: seed 5 run second (serially),
    first (its own run) or on whichever worker gives the same episode."""
    from ias_gym.evaluation import evaluate_spec

    run = {"env_kwargs": SHORT}
    both = evaluate_spec("IAS-PenRotate-v0", "random", episodes=2, seed=4, **run)  # type: ignore[arg-type]
    alone = evaluate_spec("IAS-PenRotate-v0", "random", episodes=1, seed=5, **run)  # type: ignore[arg-type]
    pool = evaluate_spec(
        "IAS-PenRotate-v0",
        "random",
        episodes=2,
        seed=4,
        backend=Backend("processes", 2),
        **run,  # type: ignore[arg-type]
    )
    assert both.returns[1] == alone.returns[0]
    assert json.dumps(both.metrics[1]) == json.dumps(alone.metrics[0])  # NaN == NaN here
    assert pool.returns == both.returns
    assert json.dumps(pool.metrics) == json.dumps(both.metrics)
    assert both.returns[0] != both.returns[1]


def test_robustness_json_is_the_same_on_2_workers(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["robustness", "--env", "IAS-PenRotate-v0", "--episodes", "2", "--seed", "1"]
    argv += ["--classes", "nominal,push_0.3N_50ms,action_noise_0.002", "--json"]
    argv += ["--env-kwargs", json.dumps(SHORT)]

    def lines(extra: list[str]) -> list[str]:
        assert main([*argv, *extra]) == 0
        return capsys.readouterr().out.strip().splitlines()

    serial = lines([])
    assert [json.loads(x)["disturbance"] for x in serial][-1] == "all"
    assert lines(["--workers", "2"]) == serial


def _skills(path: Path) -> list[tuple[dict[str, Any], dict[str, np.ndarray]]]:
    """Every skill's provenance (without id and creation time) and its arrays."""
    out = []
    with SkillDB(path, readonly=True) as db:
        for skill_id in db.ids():
            skill = db.get(skill_id)
            info = db.summary(skill_id).to_dict()
            for key in ("id", "created"):
                info.pop(key)
            arrays = {f"demo/{n}": getattr(skill.demonstration, n) for n in DEMO_ARRAYS}
            arrays |= {f"info/{k}": v for k, v in skill.demonstration.infos.items()}
            arrays |= {f"model/{n}": getattr(skill.model, n) for n in MODEL_ARRAYS}
            out.append((info, arrays))
    return out


def test_recording_on_2_workers_writes_the_serial_database(tmp_path: Path) -> None:
    """Workers return skills, this process writes them in seed order: the same database as a
    serial run, array for array, bit for bit (ids and creation times aside)."""
    argv = ["skills", "record", "--env", "IAS-PenRotate-v0", "--episodes", "4", "--seed", "2"]
    argv += ["--policy", "random", "--env-kwargs", json.dumps(RECORD_KWARGS), "--no-progress"]
    assert main([*argv, "--db", str(tmp_path / "serial.db")]) == 0
    assert main([*argv, "--db", str(tmp_path / "pool.db"), "--workers", "2"]) == 0
    _assert_same_databases(tmp_path / "serial.db", tmp_path / "pool.db", seeds=[2, 3, 4, 5])


def _assert_same_databases(a: Path, b: Path, seeds: list[int]) -> None:
    serial, other = _skills(a), _skills(b)
    assert [info["seed"] for info, _ in serial] == seeds
    assert len(other) == len(serial)
    for (info_a, arrays_a), (info_b, arrays_b) in zip(serial, other, strict=True):
        assert info_a == info_b
        assert arrays_a.keys() == arrays_b.keys()
        for name, x in arrays_a.items():
            y = arrays_b[name]
            assert (x.dtype, x.shape, x.tobytes()) == (y.dtype, y.shape, y.tobytes()), name
    # different seeds made different episodes (the comparison above is not vacuous)
    assert (
        serial[0][1]["demo/observations"].tobytes() != serial[1][1]["demo/observations"].tobytes()
    )


# ---------------------------------------------------------------- faults
def test_a_killed_worker_is_retried_once(tmp_path: Path) -> None:
    results = run_jobs(Killer(str(tmp_path), victim=3), range(8), Backend("processes", 2))
    assert [r[0] for r in results] == [i * i for i in range(8)]
    assert (tmp_path / "killed-3").exists()  # it did die once
    assert os.getpid() not in {r[1] for r in results}  # all ran in workers


def test_a_job_that_always_kills_its_worker_is_named(tmp_path: Path) -> None:
    got: list[int] = []
    with pytest.raises(WorkerError, match=r"running 5 died on every attempt") as info:
        for square, _ in iter_jobs(
            Killer(str(tmp_path), 5, always=True), range(8), Backend("processes", 2)
        ):
            got.append(square)
    assert info.value.items == [5]
    assert got == [i * i for i in range(8) if i != 5]  # every other result is there, in order


@pytest.fixture(scope="class")
def local_ray() -> Iterator[None]:
    """A local Ray for the tests of one class (the runner uses an initialised Ray as is)."""
    import ray

    # The workers import this module (its Killer job) from the tests folder: the local
    # Ray's processes inherit this process's environment.
    here = str(Path(__file__).parent)
    path = os.pathsep.join(p for p in (here, os.environ.get("PYTHONPATH")) if p)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PYTHONPATH", path)
        ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level="WARNING")
    yield
    ray.shutdown()


@needs_ray
@pytest.mark.usefixtures("local_ray")
class TestOnRay:
    def test_recording_on_ray_writes_the_serial_database(self, tmp_path: Path) -> None:
        """Skills recorded by Ray tasks come back through Ray's serialisation intact."""
        from ias_gym.skills.record import record_skills_spec

        run: dict[str, Any] = {"seed": 7, "progress": False, "env_kwargs": RECORD_KWARGS}
        record_skills_spec("IAS-PenRotate-v0", "expert", 3, tmp_path / "serial.db", **run)
        on_ray = tmp_path / "ray.db"
        record_skills_spec(
            "IAS-PenRotate-v0", "expert", 3, on_ray, backend=Backend("ray", 0), **run
        )
        _assert_same_databases(tmp_path / "serial.db", on_ray, seeds=[7, 8, 9])

    def test_a_killed_task_is_retried_once(self, tmp_path: Path) -> None:
        results = run_jobs(Killer(str(tmp_path), victim=2), range(5), Backend("ray", 0))
        assert [r[0] for r in results] == [i * i for i in range(5)]
        assert (tmp_path / "killed-2").exists()

    def test_a_task_that_always_kills_its_worker_is_named(self, tmp_path: Path) -> None:
        got: list[int] = []
        with pytest.raises(WorkerError, match=r"running 1 died") as info:
            for square, _ in iter_jobs(
                Killer(str(tmp_path), 1, always=True), range(4), Backend("ray", 0)
            ):
                got.append(square)
        assert info.value.items == [1]
        assert got == [0, 4, 9]


def test_workers_run_one_torch_thread() -> None:
    assert run_jobs(TorchThreads(), [0, 1], Backend("processes", 2)) == [1, 1]


def test_an_error_raised_by_a_job_is_raised_as_itself() -> None:
    """A bad env kwarg is the user's mistake, not a dead worker: one line, exit 2, at once."""
    from ias_gym.errors import InputError
    from ias_gym.evaluation import evaluate_spec

    with pytest.raises(InputError, match="does not accept env kwargs"):
        evaluate_spec(
            "IAS-PenRotate-v0", episodes=2, env_kwargs={"gust": 1}, backend=Backend("processes", 2)
        )


# ---------------------------------------------------------------- options
COMMANDS = [
    ["evaluate", "--env", "IAS-PenRotate-v0"],
    ["robustness", "--env", "IAS-PenRotate-v0"],
    ["skills", "record", "--env", "IAS-PenRotate-v0", "--db", "never.db"],
]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0] if c[0] != "skills" else "record")
@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--workers", "0"], "argument --workers: must be >= 1, got 0"),
        (["--workers", "2", "--ray"], "--ray and --workers N > 1 exclude each other"),
        (["--ray", "--workers", "2"], "--ray and --workers N > 1 exclude each other"),
        (["--ray", "auto", "--workers", "3"], "--ray and --workers N > 1 exclude each other"),
    ],
)
def test_bad_worker_options_are_usage_errors(
    command: list[str], options: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main([*command, *options])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("usage:")
    assert not Path("never.db").exists()


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0] if c[0] != "skills" else "record")
def test_help_shows_the_worker_defaults(
    command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        main([*command[: 2 if command[0] == "skills" else 1], "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--workers N" in text and "--ray [ADDRESS]" in text
    assert "(default: 1)" in text.split("--workers N", 2)[-1].split("--ray")[0]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0] if c[0] != "skills" else "record")
def test_ray_without_the_extra_is_one_line(
    command: list[str],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    monkeypatch.chdir(tmp_path)
    assert main([*command, "--ray"]) == 2
    err = capsys.readouterr().err
    assert err == "ias-gym: error: " + RAY_MISSING + "\n"
    assert err == (
        "ias-gym: error: --ray needs the distributed extra: pip install 'ias-gym[distributed]'\n"
    )
    assert not (tmp_path / "never.db").exists()  # refused before anything was created
