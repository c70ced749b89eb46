"""The documentation's sources: the env pages follow their docstrings, every id has a page and
a picture, the README stays short and its links resolve, and no page carries development
history (that is the CHANGELOG's). The built site in a browser: ``test_docs_browser.py``."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

import pytest
from PIL import Image

from ias_gym.rates import rate_json

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_scripts"))

import env_pages  # noqa: E402
import result_tables  # noqa: E402

ENTRIES = env_pages.registered()
README_LIMIT = 12_000  # characters
#: Development history: work sessions and rounds, issue numbers, the development persons' ids.
HISTORY = re.compile(
    r"\bsessions? \d|\bsession-\d|\bround \d|\bissue #?\d|(?<![\w/.])#\d{1,3}\b"
    r"|(?<![\w-])[pd][1-9](?![\w.-])|\bturn-\d",
    re.IGNORECASE,
)
#: Pages written for the site (the generated ones are checked where they are generated).
PAGES = sorted(p for p in DOCS.glob("*.md"))


@pytest.mark.parametrize("entry", ENTRIES, ids=[e.env_id for e in ENTRIES])
def test_every_env_id_has_a_current_page_and_a_small_picture(entry: env_pages.EnvEntry) -> None:
    page = DOCS / "envs" / f"{entry.env_id}.md"
    assert page.exists(), f"{page} is missing: run make docs"
    assert page.read_text() == env_pages.page(entry), (
        f"{page} differs from {entry.entry_point}'s docstring: run make docs and commit it"
    )
    picture = DOCS / "_static" / "envs" / f"{entry.env_id}.png"
    with Image.open(picture) as image:
        assert image.size == (320, 240)
    assert picture.stat().st_size < 60_000
    assert f"![{entry.env_id}](../_static/envs/{entry.env_id}.png)" in page.read_text()


def test_the_env_index_lists_every_id() -> None:
    index = (DOCS / "envs" / "index.md").read_text()
    assert index == env_pages.index(ENTRIES)
    for e in ENTRIES:
        assert f"[{e.env_id}]({e.env_id}.md)" in index


def test_a_docstring_role_becomes_a_qualified_myst_role() -> None:
    from ias_gym.envs.glove_grasp import GloveGraspEnv

    text = env_pages.myst_roles(":attr:`skill_start` and :class:`~ias_gym.x.Y`", GloveGraspEnv)
    assert text == (
        "{py:attr}`~ias_gym.envs.glove_grasp.GloveGraspEnv.skill_start` and "
        "{py:class}`~ias_gym.x.Y`"
    )


def test_the_readme_is_short_and_links_every_env_page() -> None:
    readme = (ROOT / "README.md").read_text()
    assert len(readme) <= README_LIMIT, f"README.md has {len(readme)} characters"
    for e in ENTRIES:
        assert f"(docs/envs/{e.env_id}.md)" in readme, f"README does not link {e.env_id}"


def test_every_relative_link_of_the_readme_resolves() -> None:
    readme = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    assert targets
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, missing


@pytest.mark.parametrize("path", [ROOT / "README.md", *PAGES], ids=lambda p: p.name)
def test_no_development_history_outside_the_changelog(path: Path) -> None:
    found = [
        f"{path.name}:{n}: {line.strip()[:100]}"
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if HISTORY.search(line)
    ]
    assert not found, "development history belongs in CHANGELOG.md:\n" + "\n".join(found)


def test_every_results_table_is_made_from_its_json() -> None:
    tables = result_tables.tables(DOCS)
    assert set(tables) == {
        "transfer.md",
        "transfer_skills.md",
        "hand_reach.md",
        "recognition.md",
        "assistance.md",
        "assist_population.md",
        "assist_residual_population.md",
        "assist_pads_population.md",
        "assist_trend_population.md",
        "assist_draws.md",
        "assist_latest_draw.md",
        "assist_acquisition.md",
        "pen_skill_bc.md",
        "pen_skill_bc_robustness.md",
        "dagger_seeds.md",
        "dagger_ensembles.md",
        "dagger_push_weighted.md",
        "dagger_gate.md",
        "dagger_combined.md",
        "sac_demos.md",
        "completion.md",
        "evaluation_pen.md",
        "learning.md",
        "robustness_pen.md",
        "robustness_shadow.md",
        "robustness_leap.md",
        "dagger.md",
        "offline_rl.md",
        *(f"{name}.md" for name in result_tables.BENCHMARKS),
    }
    for name, table in tables.items():
        assert table.count("\n|") >= 3, f"{name} has no rows"
        include = f"_generated/{name}"
        assert any(include in p.read_text() for p in PAGES), f"no page includes {include}"


def test_a_results_table_follows_its_numbers() -> None:
    result = {
        "runs": [{}],
        "persons": ["a"],
        "hands": ["ias4f"],
        "methods": ["gt"],
        "disturbances": ["nominal"],
        "summary": {
            f"ias4f|gt|nominal|{group}": {
                "runs": 2,
                "success_rate": 0.5,
                "held": 2,
                "tracked": 1,
                "margin_kept": 2,
                "rot_rms_deg": 0.25,
                "rot_rms_deg_max": 0.5,
                "pos_rms_mm": 1.0,
                "margin_err_rel": 0.123,
                "dropped": 1,
            }
            for group in ("all", "tilt_left")
        },
    }
    table = result_tables.transfer(result)
    assert (
        "| ias4f | G(t) | nominal | 2 | 50 % [9, 91] | 0 | 2 / 1 / 2 | 0.25 / 0.50 | 1.00 | "
        "12.3 % |" in (table)
    )
    assert "tilt_left" not in table  # the page shows all skills; the JSON has each class
    by_skill = result_tables.transfer_skills(result)
    assert "| gt | tilt_left | 50 % (2) |" in by_skill
    # a hand's refusals are counted where the JSON has them (older results have none)
    result["summary"]["ias4f|gt|nominal|tilt_left"]["refused"] = 1
    assert "| gt | tilt_left | 50 % (2, 1 refused) |" in result_tables.transfer_skills(result)
    assert "| all |" not in by_skill


def test_the_assistant_population_table_shows_each_arm_s_intervention() -> None:
    outcomes = {"unassisted": 0, "assisted": 3, "no_skill_knowledge": 0}
    row = {arm: rate_json([True] * k + [False] * (4 - k)) for arm, k in outcomes.items()}
    result: dict[str, Any] = {
        "set": "development",
        "persons": 2,
        "population_seed": 1,
        "operator": "closed_loop",
        "skills": [],
        "by_impairment": {"stops:at=0.4": {**row, "excluded": 1}},
    }
    table = result_tables.assist_population(result)
    assert "Intervention" not in table  # a table from before the intervention was kept
    sizes = {"unassisted": 0.0, "assisted": 0.123, "no_skill_knowledge": None}
    result["by_impairment"]["stops:at=0.4"]["intervention"] = sizes
    assert "| `stops:at=0.4` | 0.12 | - |" in result_tables.assist_population(result)


def test_the_draws_table_has_one_row_per_draw_in_order() -> None:
    """Every draw of ``ASSIST_DRAWS`` is a row, in the order run, with its persons and seed;
    a spec the draw did not run shows a dash, not another spec's rate."""
    rate = {"successes": 9, "trials": 10}
    early = {"persons": 30, "population_seed": 11, "by_impairment": {"none": {"assisted": rate}}}
    late = {
        **early,
        "population_seed": 22,
        "by_impairment": {
            "none": {"assisted": rate},
            "stops:at=0.4": {"assisted": {"successes": 3, "trials": 10}},
        },
    }
    lines = result_tables.assist_draws([("first", early), ("second", late)]).splitlines()
    body = [line for line in lines if line.startswith("| first") or line.startswith("| second")]
    assert [row.split(" | ")[1] for row in body] == ["30 of seed 11", "30 of seed 22"]
    assert body[0].endswith("| - | - | - |")
    assert body[1].endswith("| - | - | 30 % [11, 60] (3/10) |")
    drawn = [name for name, _ in result_tables.ASSIST_DRAWS]
    assert len(set(drawn)) == len(drawn) and all((DOCS / name).is_file() for name in drawn)


def readme_snippets() -> list[str]:
    """The README's Python code blocks."""
    return re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.DOTALL)


def test_the_readme_has_its_two_snippets() -> None:
    snippets = readme_snippets()
    assert len(snippets) == 2
    assert 'gym.make("IAS-PenSlide-v0")' in snippets[0] and "ExpertPolicy" in snippets[0]
    assert "record_skills" in snippets[1] and "SkillDB" in snippets[1]


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 1])
def test_every_readme_snippet_runs(index: int, tmp_path: Path) -> None:
    """Each snippet as a newcomer would run it: a fresh interpreter in an empty folder."""
    import os
    import subprocess

    script = tmp_path / "snippet.py"
    script.write_text(readme_snippets()[index])
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    done = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]


def test_the_robustness_table_follows_its_numbers() -> None:
    from ias_gym.rates import Rate

    row = Rate(1, 2).to_dict()  # the table prints a rate from its counts
    result = {
        "env": "E",
        "policy": "expert",
        "seed": 7,
        "episodes": 2,
        "set": "held-out",
        "command": "ias-gym robustness ...",
        "rows": [
            {"disturbance": "nominal", **Rate(2, 2).to_dict()},
            {"disturbance": "push", **row},
            {"disturbance": "all", "success_rate": 0.75},
        ],
    }
    table = result_tables.robustness([result, {**result, "policy": "random"}])
    assert "held-out seeds 7-8" in table
    assert "| `push` | 50 % [9, 91] (1/2) | 50 % [9, 91] (1/2) |" in table
    assert "| **minimum** | 50 % | 50 % |" in table and "`all`" not in table
    assert "| disturbance | expert `E` | random `E` |" in table


def test_the_evaluation_table_pairs_each_error_with_its_unit() -> None:
    run = {
        "success_rate": 0.5,
        "episodes": 2,
        "mean_return": 3.0,
        "mean_length": 4.0,
        "tilt_mean_deg": 1.0,
        "tilt_max_deg": 2.0,
        "drift_mean_mm": 0.5,
    }
    result = {"env": "E", "policy": "expert", "seed": 3, "episodes": 2, "command": "c"}
    table = result_tables.evaluation([{**result, "rows": [run]}])
    assert "| `E` | expert | 3-4 | 50 % [9, 91] | 3.0 | 4 | tilt 1.00 / 2.00 deg |" in table


def test_a_benchmark_table_is_its_run_and_refuses_a_foreign_file() -> None:
    result = {
        "schema": "ias-gym/bench-v1",
        "script": "bench_x.py",
        "command": "python bench/bench_x.py --steps 3",
        "date_utc": "2026-01-01 00:00",
        "machine": dict.fromkeys(
            ("cpu", "cores", "load_average_1min", "python", "mujoco", "numpy"), "m"
        ),
        "tables": [{"title": "T", "header": ["a", "b [us]"], "rows": [["x", "1.0"]]}],
        "checks": [{"goal": "b <= 2 us", "met": True, "measured": "1.0"}],
        "notes": [],
    }
    text = result_tables.benchmark(result)
    assert "`python bench/bench_x.py --steps 3`" in text and "| x | 1.0 |" in text
    assert "- met: b <= 2 us (1.0)" in text
    with pytest.raises(ValueError, match="another width"):
        result_tables.benchmark({**result, "tables": [{**result["tables"][0], "rows": [["x"]]}]})
    with pytest.raises(ValueError, match="not a benchmark"):
        result_tables.benchmark({**result, "schema": "other"})
