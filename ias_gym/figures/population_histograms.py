"""The population of simulated persons as a picture: a histogram per drawn parameter.

:func:`population_figure` draws ``n`` persons (:func:`~ias_gym.glove.population.population_ids`)
and plots the parameters that shape how a person does a skill, each against its
distribution's bounds (:data:`~ias_gym.glove.population.PARAMETERS`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ias_gym.figures._io import save_png_atomic
from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import person_parameters

#: (title, parameter of PersonParams or SkillStyle, unit) of each panel.
PANELS: tuple[tuple[str, str, str], ...] = (
    ("hand scale", "hand_scale", "-"),
    ("range of motion", "range_of_motion", "-"),
    ("movement speed", "speed", "-"),
    ("movement amplitude", "amplitude", "-"),
    ("start delay", "delay", "s"),
    ("index length", "index_length", "m"),
    ("visual delay", "visual_delay", "s"),
    ("tactile delay", "tactile_delay", "s"),
    ("grip margin", "grip_margin", "-"),
    ("tremor amplitude", "tremor", "rad"),
)


def person_rows(n: int, seed: int) -> list[dict[str, Any]]:
    """Every scalar parameter of the ``n`` persons drawn with ``seed``, one dict each (with
    ``person_id``; :func:`~ias_gym.glove.skills.person_parameters`).

    Raises:
        InputError: ``n`` < 1 or a negative seed.
    """
    return [{"person_id": p, **person_parameters(p)} for p in population_ids(n, seed)]


def population_figure(n: int, seed: int, path: Path, *, overwrite: bool = False) -> Path:
    """Histograms of :data:`PANELS` over ``n`` persons drawn with ``seed``, saved to ``path``.

    Raises:
        InputError: ``n`` < 1 or a negative seed.
        OutputExistsError: ``path`` exists and ``overwrite`` is false.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = person_rows(n, seed)
    fig, axes = plt.subplots(2, 5, figsize=(15, 5.2))
    for ax, (title, key, unit) in zip(axes.flat, PANELS, strict=True):
        ax.hist([r[key] for r in rows], bins=20, color="tab:blue", alpha=0.8)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(f"{key} [{unit}]", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(f"{n} simulated persons drawn with population seed {seed}", fontsize=11)
    fig.tight_layout()
    save_png_atomic(fig, path, overwrite=overwrite)
    plt.close(fig)
    return path
