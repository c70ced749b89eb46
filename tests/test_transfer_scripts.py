"""train/transfer_table.py counts refusals as failures; train/hand_reach.py scans a hand's reach;
train/ceiling_readings.py replays tip forces through the ceiling reading."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from ias_gym.errors import OutputExistsError
from tests.train_scripts import load_train_script


@pytest.fixture(scope="module")
def table() -> ModuleType:
    return load_train_script("transfer_table")


@pytest.fixture(scope="module")
def reach() -> ModuleType:
    return load_train_script("hand_reach")


def _run(success: bool, held_s: float = 3.0) -> dict[str, Any]:
    return {
        "success": success,
        "held": held_s >= 3.0,
        "tracked": success,
        "margin_kept": True,
        "held_s": held_s,
        "duration_s": 3.0,
        "rot_rms_deg": 0.1,
        "pos_rms_mm": 0.2,
        "margin_err_rel": 0.05,
        "refused": None,
    }


def test_a_refused_skill_is_a_failure_that_ran_nothing(table: ModuleType) -> None:
    refused = {"success": False, "refused": "too small", "duration_s": 3.0}
    summary = table.summarise([_run(True), _run(False, held_s=1.0), refused, refused])
    assert summary["runs"] == 4 and summary["refused"] == 2
    assert summary["success_rate"] == pytest.approx(1 / 4)
    # the terms and errors are over the runs that ran
    assert (summary["held"], summary["tracked"], summary["dropped"]) == (1, 1, 1)
    assert summary["rot_rms_deg"] == pytest.approx(0.1)
    row = table.markdown({"ias4f|gt|nominal|all": summary}, []).splitlines()[2]
    assert row.endswith("| 1 | 2 |")  # dropped, then refused


def test_the_probe_goes_out_along_its_direction_and_holds_there_tilting(
    reach: ModuleType,
) -> None:
    from ias_gym.sim.hands import reach_direction

    ref = reach.probe_reference(reach_direction("-y+z"), 0.006, 0.2, 1.0)
    assert ref.position.shape[1] == 3
    assert np.abs(ref.position[:, 0]).max() == 0.0
    assert np.allclose(-ref.position[:, 1], ref.position[:, 2])
    assert ref.position[:, 1].max() < 1e-6 < -ref.position[:, 1].min()
    assert np.linalg.norm(ref.position, axis=1).max() == pytest.approx(0.006, rel=1e-3)
    assert np.linalg.norm(ref.position[0]) < 1e-6
    held = ref.position[round((reach.START + reach.MOVE) / ref.dt) :]
    assert np.allclose(np.linalg.norm(held, axis=1), 0.006, rtol=1e-3)
    tilt = np.arcsin(ref.axis[:, 1])
    assert tilt.max() == pytest.approx(0.2, rel=0.02)
    # the pen starts at rest
    assert np.abs(ref.omega[:15]).max() < 1e-3 * np.abs(ref.omega).max()


def test_the_scans_stop_at_the_first_tracked_amplitude_and_the_first_failing_seed(
    reach: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a fake hand: it tilts 0.3 rad at 0.5 Hz, 0.25 at 1 Hz and 0.1 at 2 Hz (a rate of
    # 2 pi 2 0.1 = 1.26 rad/s, below 2 pi 1 0.25); it carries the pen 12 mm along +x (not
    # 14), 6 mm up at its full tilt (10 mm at less; at 8 mm its second seed fails), never
    # along +z, 14 mm every other way; it sways the pen 5 mm along x at 1 Hz and 3 mm at
    # 2 Hz (31 and 38 mm/s), 8 mm every other way
    asked: list[tuple[str, int, int]] = []
    seesaw_hz: dict[float, float] = {}
    tilt_at = {0.5: 0.3, 1.0: 0.25, 2.0: 0.1}

    def probe(
        hand: str,
        direction: str,
        amplitude: float,
        seed: int,
        tilt: float,
        hz: float,
        disturbance: str,
        sway: bool = False,
    ) -> dict[str, Any]:
        assert disturbance == reach.DISTURBANCE
        mm = round(1000 * amplitude)
        if sway:  # the speed scan: along x, 5 mm at 1 Hz and 3 mm at 2 Hz
            ok = direction != "+x" or mm <= {1.0: 5, 2.0: 3}[hz]
        elif mm == 0:  # the tilt scan
            ok = tilt <= tilt_at[hz] + 1e-9
        else:
            share = round(tilt / 0.3, 6)
            seesaw_hz[share] = hz
            if share == 1.0:
                asked.append((direction, mm, seed))
            full = share == 1.0
            ok = {
                "+x": mm <= 12,
                "+y": mm <= (6 if full else 10) or (full and mm == 8 and seed == 0),
                "+z": False,
            }.get(direction, True)
        return {"held": True, "pos_rms_mm": 0.1, "rot_rms_deg": 0.1, "tracked": bool(ok)}

    monkeypatch.setattr(reach, "probe", probe)
    out = tmp_path / "reach.json"
    assert reach.main(["--hands", "ias4f", "--seeds", "2", "--out-json", str(out)]) == 0
    result = json.loads(out.read_text())
    envelope = result["hands"]["ias4f"]
    assert envelope["tilt_rad"] == pytest.approx(0.3)
    assert envelope["tilt_rate_rad_s"] == pytest.approx(2 * math.pi * 2.0 * 0.1, abs=1e-4)
    assert envelope["sway_by_hz_mm"]["1.0"] == {"x": 5.0, "y": 8.0, "z": 8.0}
    assert envelope["speed_m_s"] == pytest.approx(2 * math.pi * 1.0 * 0.005, abs=1e-5)
    full, quarter = envelope["reach"]["1.0"], envelope["reach"]["0.25"]
    assert [full[f"{d}_mm"] for d in ("+x", "-x", "+y", "-y", "+z", "-y+z")] == [
        12.0,
        14.0,
        6.0,
        14.0,
        0.0,
        14.0,
    ]
    assert (quarter["+y_mm"], quarter["+x+y_mm"]) == (10.0, 14.0)
    # down from 14 mm: +x stops at 12, +y's 8 mm stops at its failing seed
    assert ("+x", 10, 0) not in asked and ("+y", 8, 1) in asked and ("+y", 8, 0) in asked
    assert ("+y", 4, 0) not in asked
    # the full tilt's see-saw is slowed to the tilt rate, a quarter of it is not
    assert seesaw_hz[1.0] == pytest.approx(2.0 * 0.1 / 0.3)
    assert seesaw_hz[0.25] == reach.SEESAW_HZ
    assert all(math.isfinite(p["pos_rms_mm"]) for p in result["probes"])
    # an existing output is refused before any probe runs
    asked.clear()
    with pytest.raises(OutputExistsError):
        reach.main(["--hands", "ias4f", "--out-json", str(out)])
    assert asked == []


def test_the_hands_carry_the_envelope_their_probes_measured(reach: ModuleType) -> None:
    from ias_gym.sim import hands

    measured = json.loads((Path(__file__).parents[1] / "docs" / "hand_reach.json").read_text())
    assert tuple(measured["tilt_shares"]) == hands.REACH_TILT_SHARES == reach.TILT_SHARES
    assert tuple(measured["directions"]) == hands.REACH_DIRECTIONS
    for name in hands.hand_names():
        spec, envelope = hands.get_hand(name), measured["hands"][name]
        assert spec.skill_tilt == pytest.approx(envelope["tilt_rad"], abs=1e-9)
        assert spec.skill_tilt_rate == pytest.approx(envelope["tilt_rate_rad_s"], abs=1e-4)
        expected = tuple(
            tuple(envelope["reach"][str(share)][f"{d}_mm"] / 1000.0 for d in hands.REACH_DIRECTIONS)
            for share in hands.REACH_TILT_SHARES
        )
        assert np.allclose(spec.reach_by_tilt, expected, rtol=0, atol=1e-9)


def test_the_fastest_rate_is_bound_only_by_scans_that_stopped_below_their_cap(
    reach: ModuleType,
) -> None:
    two_pi = 2 * math.pi
    # both scans stopped below the cap: the slower rate binds
    assert reach.fastest([(1.0, 0.3), (2.0, 0.125)], 0.4) == pytest.approx(two_pi * 0.25)
    # a scan that tracked its largest amplitude says nothing of the limit
    assert reach.fastest([(1.0, 0.4), (2.0, 0.2)], 0.4) == pytest.approx(two_pi * 0.4)
    # none stopped: the fastest shown is a lower bound
    assert reach.fastest([(1.0, 0.4), (2.0, 0.4)], 0.4) == pytest.approx(two_pi * 0.8)


def test_the_persons_rates_are_their_skills_peaks_in_mm_and_rad_per_s(tmp_path: Path) -> None:
    from transfer_fixtures import synthetic_skill

    from ias_gym.skills.db import SkillDB

    rates = load_train_script("skill_rates")
    db_path = tmp_path / "skills.db"
    with SkillDB(db_path) as db:
        # 20 mm up and 4 mm along the pen over a smoothstep second: a peak speed of 1.5 x
        # 20.4 mm/s; a tilt and back of 0.15 rad
        db.add(synthetic_skill(lift=0.02, tilt=0.15, name="lift_hold"))
        db.add(synthetic_skill(lift=0.0, tilt=0.0, name="tilt_left", success=False))
    out = tmp_path / "rates.json"
    assert rates.main(["--db", str(db_path), "--out-json", str(out)]) == 0
    classes = json.loads(out.read_text())["classes"]
    assert set(classes) == {"lift_hold"}  # a failed session is not counted
    lift = classes["lift_hold"]
    assert lift["sessions"] == 1
    assert lift["speed_mm_s_median"] == pytest.approx(
        1.5 * 1000 * math.hypot(0.02, 0.004), rel=0.05
    )
    assert 0.1 < lift["turn_rate_rad_s_max"] < 2.0
    with pytest.raises(OutputExistsError):
        rates.main(["--db", str(db_path), "--out-json", str(out)])


def test_the_ceiling_script_reads_a_pinned_tip_and_not_a_rising_one() -> None:
    """The replay of ``train/ceiling_readings.py``: a tip that comes back to its cone (ratio
    0.25) on six steps reads 0.25 at a plateau of five, not at one of eight; a tip whose
    ratio rises every step reads nothing; forces below ``n_min`` read nothing."""
    script = load_train_script("ceiling_readings")
    shares = [1.0, 0.5, 1.0, 1.0, 0.3, 1.0, 1.0, 0.6]  # of the cone, tip 1
    c = np.array([[1.0, 0.25 * a, 0.0, 1.0, 0.01 * (k + 1), 0.0] for k, a in enumerate(shares)])
    assert script.reading(c, 0.002, 5, 0.2, 0.01) == pytest.approx(0.25)
    assert script.reading(c, 0.002, 8, 0.2, 0.01) == 0.0
    assert script.reading(c[:, 3:], 0.002, 2, 0.2, 0.01) == 0.0  # the rising tip alone
    assert script.reading(c * 0.1, 0.002, 5, 0.2, 0.01) == 0.0
