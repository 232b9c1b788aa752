"""Scoring boxes against the truth: one :class:`Track` per localization method, the
pooled figures of bench/cooperative_cp.py and ``hilnav fleet`` (areas summed over the
robots, containment pooled), and percentiles."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

METHODS = ("ekf", "single_cp", "multi_cp")


@dataclass
class Track:
    """Per-step record of one method: box bounds, area and whether it held the truth."""

    lo: list[np.ndarray] = field(default_factory=list)
    hi: list[np.ndarray] = field(default_factory=list)
    area_m2: list[float] = field(default_factory=list)
    contained: list[bool] = field(default_factory=list)

    def record(self, lo: Sequence[float], hi: Sequence[float], truth: Sequence[float]) -> None:
        """The box [lo, hi] (x, y, theta) of one step against the truth (x, y, theta);
        headings are compared modulo 2 pi (boxes keep theta continuous)."""
        lo_a, hi_a = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        k = np.round((0.5 * (lo_a[2] + hi_a[2]) - truth[2]) / (2 * math.pi))
        tt = np.array([truth[0], truth[1], truth[2] + 2 * math.pi * k])
        self.lo.append(lo_a)
        self.hi.append(hi_a)
        self.area_m2.append(float((hi_a[0] - lo_a[0]) * (hi_a[1] - lo_a[1])))
        self.contained.append(bool(np.all((lo_a <= tt) & (tt <= hi_a))))

    def figures(self, dt: float) -> dict[str, Any]:
        """Cumulative area (m^2 s), steps contained and the second half's areas."""
        return {
            "area": float(np.sum(self.area_m2)) * dt,
            "contained": int(np.sum(self.contained)),
            "late_areas": [float(a) for a in self.area_m2[len(self.area_m2) // 2 :]],
        }


def pooled(results: Iterable[dict[str, Any]], methods: Iterable[str] = METHODS) -> dict[str, Any]:
    """Areas summed over the robots, containment pooled over robot-steps, late mean area:
    from per-robot figures ``{method}_area``, ``{method}_contained``, ``{method}_late_areas``
    and ``steps``."""
    rs = list(results)
    out: dict[str, Any] = {}
    steps = sum(r["steps"] for r in rs)
    for m in methods:
        if not all(f"{m}_area" in r for r in rs):
            continue
        out[f"{m}_area"] = round(sum(r[f"{m}_area"] for r in rs), 4)
        cont = sum(r[f"{m}_contained"] for r in rs)
        out[f"{m}_containment"] = round(cont / steps, 4) if steps else 0.0
        late = [a for r in rs for a in r[f"{m}_late_areas"]]
        out[f"{m}_late_mean_area_m2"] = round(float(np.mean(late)), 5) if late else 0.0
    if out.get("ekf_area"):
        out["multi_over_ekf_area"] = round(out["multi_cp_area"] / out["ekf_area"], 4)
    return out


def percentile(values: Sequence[float], q: float) -> float:
    """The q-th percentile (0..100), NaN for no values."""
    return float(np.percentile(values, q)) if len(values) else float("nan")
