"""What an :class:`Analysis` is shown as: the JSON summary, a human digest, the report files.

- :func:`summary_json`: the JSON summary of ``hilnav analyze`` (floats rounded to 6 digits,
  NaN and infinities as null; a part the log does not allow is left out);
- :func:`digest`: a few figures per robot, one line each (what ``hilnav demo`` prints);
- :func:`write_report`: the PNGs and ``summary.json`` in a folder.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from hilnav.analysis.result import (
    Analysis,
    BoxSummary,
    HeadingDrift,
    MapSummary,
    RobotAnalysis,
    SourceTrack,
    Stats,
)

JsonDict = dict[str, Any]


def _stats(s: Stats | None) -> JsonDict:
    if s is None:
        return {}
    return {"mean": s.mean, "rms": s.rms, "p95": s.p95, "max": s.max, "final": s.final}


def _drift(d: HeadingDrift | None) -> JsonDict:
    if d is None:
        return {}
    out: JsonDict = {"distance_m": d.distance_m}
    if d.final_deg_per_m is not None:
        out["final_deg_per_m"] = d.final_deg_per_m
    if d.slope_deg_per_m is not None:
        out["slope_deg_per_m"] = d.slope_deg_per_m
    return out


def _source(s: SourceTrack) -> JsonDict:
    out: JsonDict = {"samples": s.samples}
    if s.position is not None:
        p = s.position
        out["position_error_m"] = _stats(p.error_m)
        out["initial_position_error_m"] = p.initial_m
        out["position_error_after_rigid_fit_m"] = _stats(p.after_rigid_fit_m)
        out["rigid_fit"] = {
            "dx_m": p.rigid_fit.dx_m,
            "dy_m": p.rigid_fit.dy_m,
            "dtheta_deg": p.rigid_fit.dtheta_deg,
        }
        if p.relative_10m_m is not None:
            out["relative_error_10m_m"] = p.relative_10m_m
    if s.heading is not None:
        out["heading_error_deg"] = _stats(s.heading.error_deg)
        out["heading_drift"] = _drift(s.heading.drift)
    if s.aligned_at_start:
        out["aligned_at_start"] = True
    return out


def _boxes(b: BoxSummary) -> JsonDict:
    out: JsonDict = {
        "boxes": b.boxes,
        "empty_boxes": b.empty_boxes,
        "area_m2": {**_stats(b.area_m2), "median": b.median_area_m2},
        "theta_width_deg": _stats(b.theta_width_deg),
    }
    if b.containment is not None:
        out["judged"] = b.containment.judged
        out["contained_fraction"] = b.containment.contained_fraction
        out["violations"] = b.containment.violations
        out["judged_median_area_m2"] = b.containment.median_area_m2
    return out


def _map(m: MapSummary) -> JsonDict:
    out: JsonDict = {
        "maps_logged": m.maps_logged,
        "rows": m.rows,
        "cols": m.cols,
        "resolution_m": m.resolution_m,
        "known_cells": m.known_cells,
        "occupied_cells": m.occupied_cells,
    }
    if m.plan_error is not None:
        out["plan_error"] = m.plan_error
    if m.quality is not None:
        out["plan"] = m.plan
        out.update({f"quality_{k}": v for k, v in m.quality.as_dict().items()})
        out["match_ratio"] = m.quality.match_ratio
    if m.scores is not None:
        out["scored_against"] = m.scored_against
        out["scores"] = m.scores.as_dict()
    return out


def _robot(ra: RobotAnalysis) -> JsonDict:
    out: JsonDict = {"reference": ra.reference, "topics": dict(ra.topics)}
    if ra.reference_distance_m is not None:
        out["reference_distance_m"] = ra.reference_distance_m
    if ra.gps_fixes is not None:
        out["gps_fixes"] = asdict(ra.gps_fixes)
    if ra.truth_gaps is not None:
        out["truth_gaps"] = asdict(ra.truth_gaps)
    if ra.paths:
        out["paths"] = {name: _source(s) for name, s in ra.paths.items()}
    if ra.ekf_3sigma:
        out["ekf_3sigma"] = {
            name: {"poses": c.poses, "contained_fraction": c.contained_fraction}
            for name, c in ra.ekf_3sigma.items()
        }
    if ra.cp_boxes is not None:
        out["cp_boxes"] = _boxes(ra.cp_boxes)
    if ra.map is not None:
        out["map"] = _map(ra.map)
    if ra.heading_consistency is not None:
        out["heading_consistency"] = asdict(ra.heading_consistency)
    if ra.association is not None:
        out["association"] = asdict(ra.association)
    if ra.landmarks is not None:
        out["landmarks"] = {"maps_logged": ra.landmarks.maps_logged, "count": ra.landmarks.count}
    if ra.diagnostics:
        out["diagnostics"] = {dev: asdict(d) for dev, d in ra.diagnostics.items()}
    if ra.info is not None:
        out["robot_info"] = {
            "name": ra.info.name,
            "class": ra.info.robot_class,
            "subclass": ra.info.subclass,
        }
    return out


def _round(obj: Any, digits: int = 6) -> Any:
    if isinstance(obj, float):
        return round(obj, digits) if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _round(v, digits) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_round(v, digits) for v in obj]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return _round(float(obj), digits)
    return obj


def summary_json(analysis: Analysis) -> JsonDict:
    """The JSON summary of the analysis (what ``hilnav analyze`` prints and saves)."""
    out: JsonDict = {
        "log": analysis.log,
        "metadata": dict(analysis.metadata),
        "read": {k: v for k, v in analysis.read.as_dict().items() if k != "errors"},
        "robots": {name: _robot(ra) for name, ra in analysis.robots.items()},
    }
    if analysis.duration_s is not None:
        out["duration_s"] = analysis.duration_s
    return _round(out)


def digest(analysis: Analysis) -> list[str]:
    """A few figures per robot, one line each: path errors and drift, map, CP boxes."""
    lines = []
    if analysis.read.set_backs:
        lines.append(
            "  warning: the log's time goes back (its clock was set back while it was "
            "recorded): read in the order written; figures matched by stamp across the "
            "step are not to be trusted"
        )
    for robot in sorted(analysis.robots):
        ra = analysis.robots[robot]
        fitted = ra.reference == "gps"  # as plotted: after the rigid fit
        for src in ("pose", "heading", "odometry"):
            s = ra.paths.get(src)
            p = s.position if s is not None else None
            e = (p.after_rigid_fit_m if fitted else p.error_m) if p is not None else None
            if e is None:
                continue
            if fitted:
                lines.append(
                    f"  {robot} {src:8s} error against GPS after the rigid fit: RMS "
                    f"{e.rms:.3f} m, max {e.max:.3f} m"
                )
                continue
            drift = s.heading.drift if s.heading is not None else None
            d = drift.slope_deg_per_m if drift is not None else None
            lines.append(
                f"  {robot} {src:8s} path error mean {e.mean:.3f} m, final "
                f"{e.final:.3f} m; heading drift {d or 0:.3f} deg/m"
            )
        if ra.map is not None and ra.map.match_ratio is not None:
            lines.append(
                f"  {robot} map      match ratio {ra.map.match_ratio:.3f} "
                f"against the {ra.map.plan} plan"
            )
        sc = ra.map.scores if ra.map is not None else None
        if sc is not None:
            lines.append(
                f"  {robot} map      occupied precision {sc.occupied_precision:.3f}, recall "
                f"{sc.occupied_recall:.3f} (within {sc.tolerance_cells} cells), alignment "
                f"{sc.alignment:.3f} against the {ra.map.scored_against}"  # type: ignore[union-attr]
            )
        hc = ra.heading_consistency
        if hc is not None:
            lost = "; the filter says the heading is LOST" if hc.lost else ""
            lines.append(
                f"  {robot} heading  NEES mean {hc.mean_nees:.2f} ({100 * hc.within_99_fraction:.0f} % "
                f"within chi2 99 %), final sigma {hc.final_sigma_deg:.1f} deg, error "
                f"{hc.final_error_deg:.1f} deg{lost}"
            )
        box = ra.cp_boxes
        if box is not None and box.containment is not None:
            lines.append(
                f"  {robot} CP boxes contain the truth "
                f"{100 * box.containment.contained_fraction:.1f} % "
                f"(median area {box.containment.median_area_m2:.1f} m2)"
            )
    return lines


def write_report(analysis: Analysis, out: Path, plots: bool = True) -> JsonDict:
    """Write the PNGs (unless ``plots`` is false) and ``summary.json`` into ``out``.

    Returns the summary as saved, plus ``summary_json`` (the file's path)."""
    out.mkdir(parents=True, exist_ok=True)
    files = []
    if plots:
        from hilnav.analysis.plots import write_plots

        files = [str(f) for f in write_plots(analysis, out)]
    summary = summary_json(analysis)
    summary["plots"] = files
    (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    summary["summary_json"] = str(out / "summary.json")
    return summary
