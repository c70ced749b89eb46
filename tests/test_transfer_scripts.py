"""train/transfer_table.py counts refusals as failures; train/hand_reach.py scans a hand's reach."""

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


def test_the_probe_goes_out_and_back_along_its_axis_tilting(reach: ModuleType) -> None:
    ref = reach.probe_reference(1, 0.006, 0.2)
    assert ref.position.shape[1] == 3
    assert np.abs(ref.position[:, [0, 2]]).max() == 0.0
    assert ref.position[:, 1].max() == pytest.approx(0.006, rel=1e-3)
    assert abs(ref.position[0, 1]) < 1e-6 and abs(ref.position[-1, 1]) < 1e-6
    tilt = np.arcsin(ref.axis[:, 1])
    assert tilt.max() == pytest.approx(0.2, rel=0.02)


def test_the_reach_is_the_largest_amplitude_before_the_first_failure(
    reach: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a fake hand: tracked up to 6 mm along y at its largest tilt (10 mm at less), never
    # along z, always along x, except once at 10 mm: the scan stops there even though 12 mm
    # would pass
    asked: list[tuple[int, float]] = []

    def probe(
        hand: str, axis: int, amplitude: float, seed: int, tilt_share: float, disturbance: str
    ) -> dict[str, Any]:
        assert disturbance == "nominal"
        mm = round(1000 * amplitude)
        if tilt_share == 1.0:
            asked.append((axis, mm))
        ok = {0: mm != 10, 1: mm <= (6 if tilt_share == 1.0 else 10), 2: False}[axis]
        return {"held": True, "pos_rms_mm": 0.1, "rot_rms_deg": 0.1, "tracked": ok}

    monkeypatch.setattr(reach, "probe", probe)
    out = tmp_path / "reach.json"
    assert reach.main(["--hands", "ias4f", "--seeds", "2", "--out-json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["reach"]["ias4f"]["1.0"] == {"x_mm": 8.0, "y_mm": 6.0, "z_mm": 0.0}
    assert result["reach"]["ias4f"]["0.25"] == {"x_mm": 8.0, "y_mm": 10.0, "z_mm": 0.0}
    assert (0, 12) not in asked and (1, 8) in asked and (1, 10) not in asked
    assert all(math.isfinite(p["pos_rms_mm"]) for p in result["probes"])
    # an existing output is refused before any probe runs
    asked.clear()
    with pytest.raises(OutputExistsError):
        reach.main(["--hands", "ias4f", "--out-json", str(out)])
    assert asked == []


def test_the_hands_carry_the_reach_their_probes_measured(reach: ModuleType) -> None:
    from ias_gym.sim import hands

    measured = json.loads((Path(__file__).parents[1] / "docs" / "hand_reach.json").read_text())
    assert tuple(measured["tilt_shares"]) == hands.REACH_TILT_SHARES == reach.TILT_SHARES
    for name in hands.hand_names():
        table = measured["reach"][name]
        expected = tuple(
            tuple(table[str(share)][f"{a}_mm"] / 1000.0 for a in "xyz")
            for share in hands.REACH_TILT_SHARES
        )
        assert np.allclose(hands.get_hand(name).reach_by_tilt, expected, rtol=0, atol=1e-9)


def test_a_transfer_scales_a_lift_into_the_reach_at_its_tilt() -> None:
    from transfer_fixtures import synthetic_skill

    from ias_gym.skills.transfer import HandWorkspace, transfer_reference

    # 30 mm up and 6 mm along the pen, no turn: limited by the length, 12 mm at most (the
    # largest reach at the least probed tilt), and by y
    ws = HandWorkspace(
        0.006, 0.3, axes=((0.01, 0.012, 0.01), (0.01, 0.008, 0.01), (0.01, 0.004, 0.01))
    )
    assert ws.limits(0.0) == ws.limits(0.075) == (0.01, 0.012, 0.01)
    assert ws.limits(0.1) == (0.01, 0.008, 0.01) and ws.limits(0.3) == (0.01, 0.004, 0.01)
    ref = transfer_reference(synthetic_skill(lift=0.03, tilt=0.0), workspace=ws)
    assert ref.scale == pytest.approx(0.012 / (0.03 * math.hypot(1.0, 0.2)), rel=1e-6)
    assert np.abs(ref.position[:, 1]).max() == pytest.approx(0.03 * ref.scale, rel=0.01)
    # a turn beyond the probed tilts is held to the largest one's reach
    tilted = transfer_reference(synthetic_skill(lift=0.03, tilt=0.5), workspace=ws)
    assert tilted.scale_rotation < 1 and tilted.scale == pytest.approx(0.004 / 0.03, rel=1e-6)
