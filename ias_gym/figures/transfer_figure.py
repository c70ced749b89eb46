"""The skill-transfer figure: a person's demonstration beside both robot hands' executions.

Left column: the pen's tilt and height over time, as the person moved it through the glove
(after the grasp was established, scaled into the hands' workspace: the reference) and as
each robot hand moved it (the grip-transform expert, Theorem 1). Right column: the internal
forces ``|c_h|`` of the human pinch and of each hand's grasp, and the grasp margins
(docs/transfer.md), which the hands reproduce although their contacts, their number and
their internal forces differ from the pinch's.

    python train/transfer_table.py --figure docs/img/transfer.png [--db F --figure-id N]
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ias_gym.envs.pen_skill_env import PenSkillConfig
from ias_gym.errors import InputError
from ias_gym.figures._io import save_png_atomic
from ias_gym.outputs import check_output_file
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import (
    demonstrated_margin,
    shipped_skill_db,
    skill_start_index,
)
from ias_gym.skills.transfer_plan import plan_transfer
from ias_gym.skills.transfer_run import TransferRun, run_transfer
from ias_gym.skills.workspace import hand_names

#: The skill the figure shows by default: p1's slow see-saw in the shipped library.
DEFAULT_SKILL_ID = 2


def _tilt_deg(axis: np.ndarray) -> np.ndarray:
    return np.degrees(np.arctan2(axis[:, 1], np.hypot(axis[:, 0], axis[:, 2])))


def transfer_figure(
    out: Path | str,
    skill_db: Path | str | None = None,
    skill_id: int = DEFAULT_SKILL_ID,
    *,
    seed: int = 0,
    overwrite: bool = False,
) -> dict[str, TransferRun]:
    """Run the skill on every hand with the expert and draw the figure.

    Args:
        out: the PNG to write (atomically).
        skill_db: the skill database (default: the shipped human skills).
        skill_id: the skill to show.
        seed: the reset seed of the executions.
        overwrite: replace an existing ``out``.

    Returns:
        The executions, by hand; a hand that refuses the skill
        (:func:`~ias_gym.skills.transfer_plan.plan_transfer`) is named in the title instead.

    Raises:
        InputError: an unusable output path (checked first), an unknown skill id, or a
            skill that every hand refuses.
        OutputExistsError: ``out`` exists and ``overwrite`` is false.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = check_output_file(out, overwrite=overwrite, suffixes=(".png",), what="figure")
    db_path = Path(skill_db) if skill_db is not None else shipped_skill_db()
    with SkillDB(db_path, readonly=True) as db:
        skill = db.get(skill_id)
    runs, refused = {}, []
    for hand in hand_names():
        plan = plan_transfer(skill, hand, duration=PenSkillConfig.duration)
        if plan.refused is not None:
            refused.append(hand)  # its scaled motion would not show the skill
            continue
        runs[hand] = run_transfer(plan.reference, hand, "gt", seed=seed)[0]
    if not runs:
        raise InputError(f"every hand refuses skill {skill_id} of {db_path}; choose another")
    model = skill.model
    start = skill_start_index(skill)
    t_h = model.time[start:] - model.time[start]
    margin_h = demonstrated_margin(skill)[start:]
    c_h_h = np.linalg.norm(model.c_h[start:], axis=1)

    fig, axes = plt.subplots(2, 2, figsize=(10, 6.4), sharex=True)
    first = next(iter(runs.values()))
    ax = axes[0, 0]
    ax.plot(first.time, _tilt_deg(first.reference_axis), "k--", lw=2, label="person (reference)")
    for hand, run in runs.items():
        ax.plot(run.time, _tilt_deg(run.axis), label=f"{hand}, Theorem 1")
    ax.set_ylabel("pen tilt [deg]")
    ax.legend(fontsize=8)
    ax.set_title(f"skill {skill.name!r} of {skill.person_id}")
    ax = axes[1, 0]
    for hand, run in runs.items():
        ax.plot(
            run.time, 1000 * run.reference_position[:, 1], "--", lw=1.5, label=f"reference {hand}"
        )
        ax.plot(run.time, 1000 * run.position[:, 1], label=f"{hand}")
    ax.set_ylabel("pen height [mm]")
    ax.set_xlabel("time after the grasp [s]")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    ax.plot(t_h, c_h_h, "k", lw=2, label="person's pinch |c_h|")
    for hand, run in runs.items():
        ax.plot(run.time, np.linalg.norm(np.nan_to_num(run.internal_forces), axis=1), label=hand)
    ax.set_ylabel("internal forces |c_h| [N]")
    ax.legend(fontsize=8)
    ax.set_title("internal forces: pinch vs robot hands")
    ax = axes[1, 1]
    ax.plot(t_h, np.clip(margin_h, 0, 10), "k", lw=2, label="person")
    for hand, run in runs.items():
        ax.plot(run.time, np.clip(run.margin, 0, 10), label=hand)
    ax.set_ylabel("grasp margin m [-]")
    ax.set_xlabel("time after the grasp [s]")
    ax.axhline(1.0, color="grey", lw=0.8, ls=":")
    ax.legend(fontsize=8)
    for a in axes.ravel():
        a.grid(alpha=0.3)
    # one line per two hands, so that four hands' errors fit the figure's width
    rows = [
        f"{h}: rot {r.rot_rms_deg:.2f} deg, pos {r.pos_rms_mm:.2f} mm, margin "
        f"{100 * r.margin_err_rel:.0f} %"
        for h, r in runs.items()
        if math.isfinite(r.margin_err_rel)
    ]
    if refused:
        rows.append(f"refused (the scaled motion would not show the skill): {', '.join(refused)}")
    text = "\n".join("; ".join(rows[i : i + 2]) for i in range(0, len(rows), 2))
    fig.suptitle(f"Skill transfer (G(t)) RMS errors\n{text}", fontsize=9)
    fig.tight_layout()
    save_png_atomic(fig, path, overwrite=overwrite)
    plt.close(fig)
    return runs
