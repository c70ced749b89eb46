"""The ``ias-gym`` command and the Fig. 8 reproduction, end to end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ias_gym.cli import main
from ias_gym.grasp.pen_skill import (
    PenSkillParams,
    finger_distances,
    gravity_wrench,
    pen_wrench_matrix,
    sliding_finger,
)


@pytest.mark.parametrize("cone", ["box", "exact"])
def test_figure_wrench_intensities_writes_a_consistent_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], cone: str
) -> None:
    assert main(["figure", "wrench-intensities", "--out", str(tmp_path), "--cone", cone]) == 0
    printed = capsys.readouterr().out
    csv = tmp_path / "wrench_intensities.csv"
    png = tmp_path / "wrench_intensities.png"
    assert str(csv) in printed and str(png) in printed
    assert png.stat().st_size > 10_000
    header = csv.read_text().splitlines()[0]
    assert header == "t," + ",".join(f"c{i}" for i in range(1, 13))
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert table.shape[0] >= 400 and table[0, 0] == 0.0 and table[-1, 0] == 4.0

    # The numbers in the file are a grasp that holds the pen: net wrench zero at every t ...
    params = PenSkillParams()
    w_g = gravity_wrench(params.weight)
    for t, c in zip(table[:, 0], table[:, 1:], strict=True):
        W = pen_wrench_matrix(finger_distances(t, params))
        np.testing.assert_allclose(W @ c + w_g, 0, atol=1e-6)
        assert np.all(c[0::3] >= params.f0 - 1e-7)
        k = sliding_finger(t, params)
        if k is not None:  # ... and the sliding finger pushes with mu c_n outward
            assert c[3 * k + 1] * (-1 if k < 2 else 1) == pytest.approx(
                params.mu * c[3 * k], abs=1e-6
            )
    # The last row (t = 4 s) is the end of phase 4, not the static grasp after it: finger 4
    # still slides (c_11 = mu c_10 outward) and nothing jumps from the row before.
    last = table[-1, 1:]
    assert last[10] == pytest.approx(params.mu * last[9], abs=1e-6)
    np.testing.assert_allclose(last, table[-2, 1:], atol=1e-3)
    # docs/NOTES.md reference: the sum of the normal forces is 1.4 N throughout.
    np.testing.assert_allclose(table[:, 1::3].sum(axis=1), 1.4, atol=1e-6)


def test_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    assert "figure" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["figure", "wrench-intensities", "--help"])
    assert "--cone" in capsys.readouterr().out
