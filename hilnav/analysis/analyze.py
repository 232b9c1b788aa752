"""``hilnav analyze``: what a log allows to conclude, per robot, as a typed :class:`Analysis`.

Per robot (topics ``/<robot>/<kind>``, read by tracks.py), against the reference — ``truth``
(msgs.GroundTruth: the fakes', or a data set's motion capture, whose gaps are not scored)
or, without truth, the GPS east/north fixes (position only):

- path error and heading drift per metre of every pose source (errors.py);
- the last map against the floor plan or the log's reference map (maps.py);
- the heading filter's NEES against a reference heading (consistency.py), and what the
  data association did and why;
- CP box containment and areas, EKF 3-sigma containment (containment.py);
- diagnostics summary per device (last counters, bad frames, reconnects, errors);
- landmark maps and the robot's info, when logged.

The JSON summary and the human digest are made from the result in report.py, the PNGs in
plots.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hilnav.analysis.consistency import heading_consistency
from hilnav.analysis.containment import box_series, box_summary, ekf_containment
from hilnav.analysis.errors import SourceErrors, source_errors, source_track
from hilnav.analysis.geometry import path_length
from hilnav.analysis.gps_error import WINDOW_S, gps_inliers, travelled_from_speed
from hilnav.analysis.maps import map_summary
from hilnav.analysis.result import (
    Analysis,
    AssociationSummary,
    DeviceSummary,
    GpsFixes,
    LandmarkSummary,
    RobotAnalysis,
    RobotSeries,
    TruthGaps,
)
from hilnav.analysis.tracks import NS, RobotLog, Track, load
from hilnav.log.reader import ReadStats, read_metadata
from msgs import DeviceDiagnostics


def diagnostics_summary(diags: dict[str, list[DeviceDiagnostics]]) -> dict[str, DeviceSummary]:
    """Per device: the last counters, the connected fraction, the mean rate, the errors."""
    out = {}
    for dev in sorted(diags):
        ds = diags[dev]
        last = ds[-1]
        rates = [d.rate_hz for d in ds if d.connected]
        errors = sorted({d.last_error for d in ds if d.last_error})
        out[dev] = DeviceSummary(
            reports=len(ds),
            connected_fraction=sum(d.connected for d in ds) / len(ds),
            frames_ok=last.frames_ok,
            bad_checksums=last.bad_checksums,
            resyncs=last.resyncs,
            bytes_skipped=last.bytes_skipped,
            frames_lost=last.frames_lost,
            reconnects=last.reconnects,
            mean_rate_hz=float(np.mean(rates)) if rates else 0.0,
            errors=errors[:5],
            malformed=last.malformed,
            duplicates=last.duplicates,
        )
    return out


def reference_of(rl: RobotLog) -> tuple[Track, str, bool]:
    """The robot's reference track, its name, and whether it has a heading."""
    if len(rl.truth) >= 2:
        return rl.truth, "truth", True
    if len(rl.gps) >= 2:
        return rl.gps, "gps", False
    return Track(), "none", False


def gps_keep(rl: RobotLog) -> tuple[np.ndarray, str | None]:
    """The robot's GPS fixes (time order) kept by the outlier rule of gps_error, judged by
    the distance the controls' speeds or else the odometry say was travelled (all kept
    when the log has neither), and what that distance came from."""
    t, x, y, _ = rl.gps.arrays()
    if len(rl.speeds) >= 2:
        ts, v = np.array(sorted(rl.speeds)).T
        travel_t, travel, source = ts, travelled_from_speed(ts, v, ns=True), "controls"
    elif len(rl.sources.get("odometry", ())) >= 2:
        travel_t, ox, oy, _ = rl.sources["odometry"].arrays()
        travel, source = path_length(ox, oy), "odometry"
    else:
        return np.ones(len(t), dtype=bool), None
    return gps_inliers(t, x, y, travel_t, travel, window=WINDOW_S * NS), source


def association_summary(rl: RobotLog) -> AssociationSummary | None:
    """The association's checks by outcome, and their reasons (numbers stripped)."""
    if not rl.associations:
        return None
    import re
    from collections import Counter

    outcomes = Counter(r.outcome for r in rl.associations)
    reasons = Counter(
        f"{r.outcome}: " + re.sub(r"-?\d+(\.\d+)?", "#", r.reason) for r in rl.associations
    )
    return AssociationSummary(len(rl.associations), dict(sorted(outcomes.items())),
                              dict(sorted(reasons.items())))  # fmt: skip


def analyze_robot(
    rl: RobotLog, plan_name: str | None, meta: dict[str, str] | None = None
) -> RobotAnalysis:
    """Every figure the robot's messages allow (see the module docstring)."""
    ref, ref_name, ref_heading = reference_of(rl)
    keep, fixes = None, None
    if ref_name == "gps":
        keep, travelled_from = gps_keep(rl)
        fixes = GpsFixes(len(keep), int(np.count_nonzero(~keep)), travelled_from)
    errs: dict[str, SourceErrors] = {}
    for name in sorted(rl.sources):
        if name == "gyro" and not ref_heading:
            continue
        e = source_errors(name, rl.sources[name], ref, ref_heading, keep)
        if e is not None:
            errs[name] = e
    bs = box_series(rl)
    ra = RobotAnalysis(
        name=rl.name,
        reference=ref_name,
        gps_fixes=fixes,
        topics=dict(sorted(rl.counts.items())),
        series=RobotSeries(rl, errs, bs, keep),
        paths={name: source_track(name, e, ref_heading) for name, e in errs.items()},
        cp_boxes=box_summary(bs) if bs is not None else None,
        map=map_summary(rl, plan_name, meta),
        association=association_summary(rl),
        diagnostics=diagnostics_summary(rl.diagnostics),
        info=rl.info,
    )
    if ref_name == "truth" and ref.gaps:
        spans = [(hi - lo) / NS for lo, hi in ref.gaps]
        ra.truth_gaps = TruthGaps(len(spans), float(sum(spans)), float(max(spans)))
    if len(ref) >= 2:
        _, rx, ry, _ = ref.arrays()
        ra.reference_distance_m = float(path_length(rx, ry)[-1])
    if ref_name == "truth" and "heading" in rl.sources:
        ra.heading_consistency = heading_consistency(rl.sources["heading"], ref)
    if ref_name == "truth":
        for name, tr in sorted(rl.sources.items()):
            c = ekf_containment(tr, ref)
            if c is not None:
                ra.ekf_3sigma[name] = c
    if rl.landmarks is not None:
        ra.landmarks = LandmarkSummary(maps_logged=rl.landmark_maps, count=len(rl.landmarks.xs))
    return ra


def analyze(path: str | Path, plan: str | None = None) -> Analysis:
    """Analyse a log: the figures of each robot and the series for the plots.

    ``plan`` overrides the floor plan named in the log's "hilnav" metadata."""
    stats = ReadStats()
    robots = load(path, stats)
    meta = read_metadata(path).get("hilnav", {})
    plan_name = plan or meta.get("plan") or None
    result = Analysis(
        log=str(path),
        metadata=dict(sorted(meta.items())),
        read=stats,
        robots={name: analyze_robot(robots[name], plan_name, meta) for name in sorted(robots)},
        plan_name=plan_name,
    )
    all_t = [
        tr.t for rl in robots.values() for tr in [rl.truth, rl.gps, *rl.sources.values()] if tr.t
    ]
    if all_t:
        lo = min(min(t) for t in all_t)
        hi = max(max(t) for t in all_t)
        result.duration_s = (hi - lo) / NS
    return result
