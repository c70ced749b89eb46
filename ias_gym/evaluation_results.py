"""The outcome of evaluation episodes and their summary: per-episode outcomes
(:class:`EpisodeOutcome`, what a worker sends back), the :class:`EvaluationResult` that
collects them, and its statistics (success rate, mean return, mean/max of each task metric
in the units of :data:`METRIC_UNITS`).

:func:`ias_gym.evaluation.evaluate` and :func:`ias_gym.evaluation.evaluate_spec` fill one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Unit of each task metric in the summary: ``metric -> (summary name, unit, factor)``; the
#: envs report SI (m, rad, N), the summary mm, deg and percent, named in every key.
METRIC_UNITS: Mapping[str, tuple[str, str, float]] = {
    "final_slide_error": ("final_slide_error", "mm", 1e3),
    "max_position_error": ("max_position_error", "mm", 1e3),
    "max_pen_tilt": ("max_pen_tilt", "deg", math.degrees(1.0)),
    "rms_tilt_error": ("rms_tilt_error", "deg", math.degrees(1.0)),
    "rms_tilt_error_fraction": ("rms_tilt_error_of_amplitude", "pct", 100.0),
    "pen_height": ("pen_height", "mm", 1e3),
    "pinch_force": ("pinch_force", "N", 1.0),
}


@dataclass(frozen=True)
class EpisodeOutcome:
    """One episode's outcome (what a worker sends back: plain numbers).

    Attributes:
        is_success: the env's ``is_success`` at the end.
        episode_return: the sum of the rewards [-].
        length: number of steps.
        metrics: the env's ``episode_metrics`` (SI units; NaN: not defined).
    """

    is_success: bool
    episode_return: float
    length: int
    metrics: dict[str, float]


@dataclass
class EvaluationResult:
    """Per-episode outcomes and their summary (see :meth:`summary`)."""

    env_id: str
    policy: str
    successes: list[bool] = field(default_factory=list)
    returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    metrics: list[dict[str, float]] = field(default_factory=list)

    def add(self, outcome: EpisodeOutcome) -> None:
        """Append one episode's outcome."""
        self.successes.append(outcome.is_success)
        self.returns.append(outcome.episode_return)
        self.lengths.append(outcome.length)
        self.metrics.append(outcome.metrics)

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: success rate, mean return, and mean/max of each task metric.

        Each metric's keys name its statistic and unit, ``<metric>_<mean|max>_<unit>``
        (``max_position_error_max_mm``, ``max_pen_tilt_mean_deg``, ``pinch_force_max_N``,
        :data:`METRIC_UNITS`); a metric without a known unit keeps the env's SI value
        and ends in ``_si``. ``None``: the metric was not defined in any episode.
        """
        out: dict[str, Any] = {
            "env": self.env_id,
            "policy": self.policy,
            "episodes": len(self.successes),
            "success_rate": float(np.mean(self.successes)) if self.successes else 0.0,
            "mean_return": float(np.mean(self.returns)) if self.returns else 0.0,
            "mean_length": float(np.mean(self.lengths)) if self.lengths else 0.0,
        }
        for key in self.metrics[0] if self.metrics else ():
            name, unit, factor = METRIC_UNITS.get(key, (key, "si", 1.0))
            values = factor * np.array([m[key] for m in self.metrics])
            values = values[np.isfinite(values)]  # NaN: not defined for that episode
            out[f"{name}_mean_{unit}"] = float(values.mean()) if len(values) else None
            out[f"{name}_max_{unit}"] = float(values.max()) if len(values) else None
        return out


__all__ = ["METRIC_UNITS", "EpisodeOutcome", "EvaluationResult"]
