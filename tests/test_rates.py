"""The evaluation protocol: Wilson intervals and rates."""

from __future__ import annotations

import math

import pytest

from ias_gym.errors import InputError
from ias_gym.rates import Rate, check_set_kind, wilson_interval


def test_the_wilson_interval_of_known_cases() -> None:
    # 0 of 10: the upper bound is z^2 / (n + z^2) = 0.2775 (Brown, Cai & DasGupta 2001)
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.27753, abs=1e-4)
    low, high = wilson_interval(10, 10)
    assert high == 1.0 and low == pytest.approx(1 - 0.27753, abs=1e-4)
    low, high = wilson_interval(50, 100)
    assert (low, high) == pytest.approx((0.4038, 0.5962), abs=1e-4)


@pytest.mark.parametrize("k, n", [(0, 1), (3, 7), (29, 30), (97, 100), (500, 1000)])
def test_the_interval_holds_the_rate_and_shrinks_with_more_trials(k: int, n: int) -> None:
    low, high = wilson_interval(k, n)
    assert 0.0 <= low <= k / n <= high <= 1.0
    low4, high4 = wilson_interval(4 * k, 4 * n)
    assert high4 - low4 < high - low


@pytest.mark.parametrize("k, n", [(-1, 5), (6, 5), (0, 0)])
def test_impossible_counts_are_refused(k: int, n: int) -> None:
    with pytest.raises(InputError):
        wilson_interval(k, n)


def test_a_rate_reports_its_interval() -> None:
    rate = Rate.of([True] * 29 + [False])
    fields = rate.to_dict()
    assert fields["successes"] == 29 and fields["trials"] == 30
    assert fields["ci95_low"] < fields["success_rate"] < fields["ci95_high"]
    assert math.isclose(fields["success_rate"], 29 / 30)
    assert "97 %" in str(rate) and "29/30" in str(rate)
    with pytest.raises(InputError):
        Rate.of([])


def test_a_set_is_development_or_held_out() -> None:
    assert check_set_kind("held-out") == "held-out"
    with pytest.raises(InputError):
        check_set_kind("test")


def test_a_rate_near_all_or_none_does_not_read_as_all_or_none() -> None:
    """199 of 200 rounds to 100 in whole percent: it prints 99.5; a whole rate stays whole."""
    from ias_gym.rates import Rate

    assert str(Rate(199, 200)).startswith("99.5 % [")
    assert str(Rate(1, 400)).startswith("0.2 % [")
    assert str(Rate(200, 200)).startswith("100 % [") and str(Rate(0, 50)).startswith("0 % [")
    assert str(Rate(39, 40)).startswith("98 % [")  # 97.5 rounds to a value that is not 100
