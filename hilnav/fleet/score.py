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
TWO_PI = 2 * math.pi


@dataclass
class Track:
    """Per-step record of one method: box bounds, area and whether it held the truth."""

    lo: list[tuple[float, float, float]] = field(default_factory=list)
    hi: list[tuple[float, float, float]] = field(default_factory=list)
    area_m2: list[float] = field(default_factory=list)
    contained: list[bool] = field(default_factory=list)

    def record(self, lo: Sequence[float], hi: Sequence[float], truth: Sequence[float]) -> None:
        """The box [lo, hi] (x, y, theta) of one step against the truth (x, y, theta);
        headings are compared modulo 2 pi (the box's heading taken 2 pi k from the truth's
        that puts it nearest the box's middle; boxes may keep theta continuous)."""
        lo_t = (float(lo[0]), float(lo[1]), float(lo[2]))
        hi_t = (float(hi[0]), float(hi[1]), float(hi[2]))
        q = (0.5 * (lo_t[2] + hi_t[2]) - truth[2]) / TWO_PI
        k = float(round(q)) if math.isfinite(q) else q  # half to even, as numpy's
        tt = (float(truth[0]), float(truth[1]), truth[2] + TWO_PI * k)
        self.lo.append(lo_t)
        self.hi.append(hi_t)
        self.area_m2.append((hi_t[0] - lo_t[0]) * (hi_t[1] - lo_t[1]))
        self.contained.append(all(a <= t <= b for a, t, b in zip(lo_t, tt, hi_t, strict=True)))

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
