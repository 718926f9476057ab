"""Means and rates over episodes with their 95% confidence intervals (Student t; Wilson score for rates)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

STUDENT_T, WILSON = "student_t", "wilson"
Z_95 = float(stats.norm.ppf(0.975))  # two-sided 95% quantile of the standard normal
INTERVAL_NOTES = {
    STUDENT_T: "mean ± half-width of its 95% confidence interval (Student t)",
    WILSON: "rate [low, high]: its 95% confidence interval (Wilson score)",
}


def summary_of(metric, values) -> dict:
    """The JSON summary of the per-episode ``values``: a Wilson rate for a proportion, else a Student t mean."""
    return (ProportionSummary if metric.proportion else Summary).of(values).as_dict()


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of ``successes / trials`` (``ValueError`` unless ``0 <= successes <= trials``)."""
    if trials < 1 or not 0 <= successes <= trials:
        raise ValueError(f"a proportion needs 0 <= successes <= trials and trials >= 1, got {successes} of {trials}")
    rate, z2 = successes / trials, z * z
    center = (rate + z2 / (2 * trials)) / (1 + z2 / trials)
    half_width = z / (1 + z2 / trials) * math.sqrt(rate * (1 - rate) / trials + z2 / (4 * trials * trials))
    return max(0.0, center - half_width), min(1.0, center + half_width)


@dataclass(frozen=True)
class Summary:
    """The mean of a metric over episodes and the half-width of its 95% confidence interval (Student t)."""

    mean: float
    ci95: float  # nan for a single episode

    @classmethod
    def of(cls, values) -> Summary:
        values = np.asarray(values, dtype=float)
        if len(values) < 2:
            return cls(float(values.mean()), float("nan"))
        half_width = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values))
        return cls(float(values.mean()), float(half_width))

    def as_dict(self) -> dict:
        return {"mean": self.mean, "ci95": self.ci95, "interval": STUDENT_T}


@dataclass(frozen=True)
class ProportionSummary:
    """The rate of a 0/1 metric over episodes and its 95% Wilson score interval ``[low, high]``."""

    mean: float
    low: float
    high: float

    @classmethod
    def of(cls, values) -> ProportionSummary:
        """Raises ``ValueError`` if a value is not 0 or 1."""
        values = np.asarray(values, dtype=float)
        if not np.isin(values, (0.0, 1.0)).all():
            raise ValueError(f"a proportion metric takes values 0 or 1 per episode, got {values.tolist()}")
        return cls(float(values.mean()), *wilson_interval(int(values.sum()), len(values)))

    def as_dict(self) -> dict:
        return {"mean": self.mean, "ci95_low": self.low, "ci95_high": self.high, "interval": WILSON}


def interval_cell(summary: dict) -> str:
    """A summary as a table cell: ``mean ± half-width`` (Student t) or ``rate [low, high]`` (Wilson)."""
    if summary["interval"] == WILSON:
        return f"{summary['mean']:.3f} [{summary['ci95_low']:.3f}, {summary['ci95_high']:.3f}]"
    if math.isnan(summary["ci95"]):  # one episode: no interval
        return f"{summary['mean']:.3f} ± n/a"
    return f"{summary['mean']:.3f} ± {summary['ci95']:.3f}"


def error_bar(summary: dict) -> tuple[float, float]:
    """The distances below and above the mean to the ends of its 95% interval (0 where undefined)."""
    if summary["interval"] == WILSON:
        return summary["mean"] - summary["ci95_low"], summary["ci95_high"] - summary["mean"]
    half_width = 0.0 if math.isnan(summary["ci95"]) else summary["ci95"]
    return half_width, half_width
