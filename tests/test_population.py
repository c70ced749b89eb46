"""The person population: documented distributions, reproducible ids, checked input."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import asdict

import numpy as np
import pytest

from ias_gym.errors import InputError
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.population import (
    NOMINAL_HAND_LENGTH,
    PARAMETERS,
    Distribution,
    PersonStream,
    check_population,
    parameter,
    population_ids,
)
from ias_gym.glove.skills import SkillStyle


@pytest.mark.parametrize("name", sorted(PARAMETERS))
def test_every_parameter_draws_inside_its_bounds_and_monotonically(name: str) -> None:
    dist = PARAMETERS[name].distribution
    u = np.linspace(0.0, 1.0, 101)
    values = np.array([dist.draw(float(x)) for x in u])
    assert values[0] == pytest.approx(dist.low) and values[-1] == pytest.approx(dist.high)
    assert np.all(np.diff(values) >= 0.0)
    assert PARAMETERS[name].source and PARAMETERS[name].unit


def test_a_symmetric_normal_has_its_mean_as_median_and_a_lognormal_its_median() -> None:
    normal = Distribution("normal", 0.12, 0.02, 0.08, 0.16)
    assert normal.draw(0.5) == pytest.approx(0.12)
    lognormal = Distribution("lognormal", 1.0, 0.1, 0.5, 2.0)
    assert lognormal.draw(0.5) == pytest.approx(1.0, abs=1e-6)
    # a truncated normal's quantiles: u = Phi(1) of the untruncated at +1 sd when far bounds
    wide = Distribution("normal", 0.0, 1.0, -50.0, 50.0)
    assert wide.draw(0.8413447460685429) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(
    "args",
    [
        ("normal", math.nan, 1.0, 0.0, 1.0),
        ("normal", 0.0, -1.0, -1.0, 1.0),
        ("uniform", 0.0, 0.0, 1.0, 1.0),
        ("lognormal", -1.0, 0.1, 0.1, 1.0),
    ],
)
def test_an_invalid_distribution_is_refused(args: tuple) -> None:
    with pytest.raises(InputError):
        Distribution(*args)


def test_an_unknown_parameter_lists_the_known_ones() -> None:
    with pytest.raises(KeyError, match="hand_length_men"):
        parameter("hand_size")


def test_a_person_is_the_same_for_the_same_id_and_another_for_another() -> None:
    assert PersonParams.sample("q17") == PersonParams.sample("q17")
    assert SkillStyle.sample("q17") == SkillStyle.sample("q17")
    assert PersonParams.sample("q17") != PersonParams.sample("q18")
    # the hand's and the style's streams are apart: the same id, unrelated numbers
    hand = PersonStream("q17", "hand").rng.random()
    style = PersonStream("q17", "style").rng.random()
    assert hand != style


def test_the_drawn_population_matches_its_documented_distributions() -> None:
    ids = population_ids(1500, 99)
    people = [PersonParams.sample(p) for p in ids]
    styles = [SkillStyle.sample(p) for p in ids]
    lengths = np.array([p.hand_scale for p in people]) * NOMINAL_HAND_LENGTH
    # a half-and-half mixture of N(190, 10) and N(174, 9) mm: mean 182, sd about 12 mm
    assert np.mean(lengths) == pytest.approx(0.182, abs=0.0015)
    assert 0.010 < np.std(lengths) < 0.0135
    assert np.median([s.visual_delay for s in styles]) == pytest.approx(0.12, abs=0.004)
    margins = np.array([s.grip_margin for s in styles])
    assert margins.min() >= 0.1 and margins.max() <= 0.4
    for name, values in (
        ("range_of_motion", [p.range_of_motion for p in people]),
        ("speed", [s.speed for s in styles]),
        ("tactile_delay", [s.tactile_delay for s in styles]),
    ):
        dist = PARAMETERS[name].distribution
        assert dist.low <= min(values) and max(values) <= dist.high
        assert max(values) - min(values) > 0.5 * (dist.high - dist.low)  # spread, not a constant


def test_population_ids_are_reproducible_unique_and_apart_between_seeds() -> None:
    a = population_ids(40, 1)
    assert a == population_ids(40, 1)
    assert len(set(a)) == 40
    assert set(a).isdisjoint(population_ids(40, 2))
    assert population_ids(3, 1) == a[:3]  # the k-th person of a seed is always the same


@pytest.mark.parametrize("n, seed", [(0, 1), (-3, 1), (2, -1), (True, 1), (2.5, 1), ("5", 1)])
def test_an_invalid_population_draw_names_the_value(n: object, seed: object) -> None:
    with pytest.raises(InputError, match="population"):
        check_population(n, seed)


def test_a_hand_of_no_size_is_refused_with_its_value() -> None:
    values = asdict(PersonParams.nominal())
    for bad in (math.nan, -0.9, 0.0):
        with pytest.raises(InputError, match="hand_scale"):
            PersonParams(**{**values, "hand_scale": bad})


def test_the_population_command_refuses_bad_input_in_one_line(tmp_path) -> None:
    def run(*args: str) -> subprocess.CompletedProcess[str]:
        cmd = [sys.executable, "-m", "ias_gym.cli", "population", *args]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=120)

    bad = run("--population", "0")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "0" in bad.stderr
    plot = tmp_path / "pop.png"
    plot.write_bytes(b"keep")
    refused = run("--population", "2", "--plot", str(plot))
    assert refused.returncode == 2 and plot.read_bytes() == b"keep"
    ok = run("--population", "3", "--population-seed", "4", "--json")
    assert ok.returncode == 0 and len(ok.stdout.strip().splitlines()) == 3


def test_a_failed_session_says_why_and_a_place_needs_a_lift_first() -> None:
    from ias_gym.skills.completion import REASONS, failure_reason

    assert failure_reason("tilt_left", True, False, "", True) == ""
    assert failure_reason("tilt_left", False, True, "", True) == "dropped"
    assert failure_reason("lift_hold", False, False, "out of reach", False) == "person"
    assert failure_reason("lift_hold", False, False, "", False) == "not lifted"
    # a lift_place that never reached the lift height was not lifted, not misplaced
    assert failure_reason("lift_place", False, False, "", False) == "not lifted"
    assert failure_reason("lift_place", False, False, "", True) == "not placed"
    cases = [
        (s, ok, d, det, li)
        for s in ("lift_place", "seesaw_fast")
        for ok in (0, 1)
        for d in (0, 1)
        for det in ("", "x")
        for li in (0, 1)
    ]
    assert {
        failure_reason(s, bool(ok), bool(d), det, bool(li)) for s, ok, d, det, li in cases
    } <= set(REASONS)
