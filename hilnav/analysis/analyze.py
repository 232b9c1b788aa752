"""``hilnav analyze``: what a log allows to conclude, as a JSON summary (plots in plots.py).

Per robot (topics ``/<robot>/<kind>``). Times are the messages' own stamps (``stamp_ns``:
one host clock in the daemon, the device read time, carried over to the estimates), or the
MCAP log time for a message without one — log times of service outputs are when the
service loop got to them, which lags behind when the loop stalls.

- **path error** of every pose source — ``pose`` (pose EKF), ``heading`` (heading filter's
  dead reckoning), ``odometry`` (raw ARCOS odometry in ``odom``, aligned to the reference
  at its first sample, as is the heading filter's dead reckoning) ... — against the reference, interpolated in time:
  ``truth`` (msgs.GroundTruth, fakes only) or, without truth, the GPS east/north fixes
  (position only). Mean, RMS, p95, max and final position and heading errors.
- **heading drift per metre** (ir-grid-mapping.txt, eq. 2: encoders drift by about
  alpha = 3 deg/m): final |heading error| over the distance travelled, and the
  least-squares slope of |heading error| against distance; also for the gyro's integrated
  angle (aligned at its first sample).
- **map match ratio** (ir-grid-mapping.txt §4) of the last ``map`` (foxglove.Grid) against
  the floor plan named in the log's "hilnav" metadata (``plan``), via mapping.quality.
- **CP containment** (ekf-vs-cp.txt): fraction of ``pose_box`` boxes containing the truth,
  their areas; and, for comparison, the fraction of EKF poses inside their 3-sigma bounds.
- **diagnostics** summary per device (last counters, bad frames, reconnects, errors).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hilnav.log.foxglove import split_topic
from hilnav.log.reader import ReadStats, decode_record, iter_raw, message_types, read_metadata
from msgs import (
    DeviceDiagnostics,
    GpsFix,
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    OccupancyGridMsg,
    PoseBox,
    PoseEstimate,
    RobotInfo,
    RobotOdometry,
)

NS = 1_000_000_000
# Sources in their own frame (dead reckoning from where they started): compared after a
# rigid alignment of their first sample to the reference.
DEAD_RECKONING = ("odometry", "gyro", "heading")


@dataclass
class Track:
    """A time series of planar poses (log times in ns)."""

    t: list[int] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    theta: list[float] = field(default_factory=list)
    var: list[tuple[float, float, float]] = field(default_factory=list)  # sx^2, sy^2, st^2

    def add(self, t: int, x: float, y: float, theta: float, var=None) -> None:  # noqa: ANN001
        self.t.append(int(t))
        self.x.append(float(x))
        self.y.append(float(y))
        self.theta.append(float(theta))
        if var is not None:
            self.var.append(var)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(self.t, dtype=np.int64)
        order = np.argsort(t, kind="stable")
        return (
            t[order],
            np.asarray(self.x)[order],
            np.asarray(self.y)[order],
            np.asarray(self.theta)[order],
        )

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class RobotLog:
    """Everything of one robot that the analysis uses."""

    name: str
    truth: Track = field(default_factory=Track)
    sources: dict[str, Track] = field(default_factory=dict)  # pose, heading, odometry, gyro
    gps: Track = field(default_factory=Track)
    boxes: list[tuple[int, PoseBox]] = field(default_factory=list)
    last_map: OccupancyGridMsg | None = None
    maps: int = 0
    diagnostics: dict[str, list[DeviceDiagnostics]] = field(default_factory=dict)
    info: RobotInfo | None = None
    landmarks: Any = None  # the last landmark map (msgs.landmarks.LandmarkMap: xs, ys)
    landmark_maps: int = 0
    counts: Counter = field(default_factory=Counter)


def load(path: str | Path, stats: ReadStats | None = None) -> dict[str, RobotLog]:
    """Group a log's messages by robot (raw bytes are skipped, not decoded)."""
    st = stats if stats is not None else ReadStats()
    types = message_types()
    robots: dict[str, RobotLog] = {}
    for r in iter_raw(path, stats=st):
        robot, kind = split_topic(r.topic)
        if kind.startswith("raw/") or kind.startswith("fox/") or not robot:
            continue
        m = decode_record(r, st, types)
        if m is None:
            continue
        rl = robots.setdefault(robot, RobotLog(robot))
        rl.counts[kind] += 1
        msg = m.msg
        stamp = getattr(msg, "stamp_ns", None)
        t = stamp if isinstance(stamp, int) and stamp > 0 else m.log_time_ns
        if isinstance(msg, GroundTruth):
            rl.truth.add(t, msg.pose.x, msg.pose.y, msg.pose.theta)
        elif isinstance(msg, PoseEstimate):
            c = msg.covariance
            var = (c[0], c[4], c[8]) if len(c) == 9 else None
            rl.sources.setdefault(kind, Track()).add(t, msg.pose.x, msg.pose.y, msg.pose.theta, var)
        elif isinstance(msg, HeadingEstimate):
            rl.sources.setdefault(kind, Track()).add(t, msg.pose.x, msg.pose.y, msg.theta_rad)
        elif isinstance(msg, RobotOdometry):
            rl.sources.setdefault("odometry", Track()).add(
                t, msg.pose.x, msg.pose.y, msg.pose.theta
            )
        elif isinstance(msg, GyroSample):
            rl.sources.setdefault("gyro", Track()).add(t, math.nan, math.nan, msg.angle_rad)
        elif isinstance(msg, GpsFix):
            if msg.east_m is not None and msg.north_m is not None:
                rl.gps.add(t, msg.east_m, msg.north_m, math.nan)
        elif isinstance(msg, PoseBox):
            rl.boxes.append((t, msg))
        elif isinstance(msg, OccupancyGridMsg):
            rl.last_map = msg
            rl.maps += 1
        elif isinstance(msg, DeviceDiagnostics):
            rl.diagnostics.setdefault(msg.device, []).append(msg)
        elif isinstance(msg, RobotInfo):
            rl.info = msg
        elif hasattr(msg, "xs") and hasattr(msg, "ys") and hasattr(msg, "ids"):
            rl.landmarks = msg
            rl.landmark_maps += 1
    return robots


# ---------------------------------------------------------------------------------------
# Numerics.


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    w = np.remainder(np.asarray(a, dtype=float) + math.pi, 2.0 * math.pi) - math.pi
    return np.where(w == -math.pi, math.pi, w)


def interp_pose(
    ref_t: np.ndarray, ref_x: np.ndarray, ref_y: np.ndarray, ref_th: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reference pose at times ``t`` (linear; heading unwrapped first); mask of t in range."""
    ok = (t >= ref_t[0]) & (t <= ref_t[-1]) if len(ref_t) else np.zeros(len(t), bool)
    tf, rf = t.astype(float), ref_t.astype(float)
    x = np.interp(tf, rf, ref_x)
    y = np.interp(tf, rf, ref_y)
    th = (
        wrap(np.interp(tf, rf, np.unwrap(ref_th)))
        if np.all(np.isfinite(ref_th))
        else np.full(len(t), np.nan)
    )
    return x, y, th, ok


def _stats(e: np.ndarray) -> dict[str, float]:
    e = np.abs(e[np.isfinite(e)])
    if e.size == 0:
        return {}
    return {
        "mean": float(e.mean()),
        "rms": float(np.sqrt(np.mean(e**2))),
        "p95": float(np.percentile(e, 95)),
        "max": float(e.max()),
        "final": float(e[-1]),
    }


def path_length(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Cumulative distance along a path (m), 0 at the first point."""
    if len(x) == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])


def align_at_start(
    x: np.ndarray, y: np.ndarray, th: np.ndarray, rx: float, ry: float, rth: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move a track rigidly so that its first pose equals the reference pose (rx, ry, rth)."""
    dth = rth - th[0]
    c, s = math.cos(dth), math.sin(dth)
    dx, dy = x - x[0], y - y[0]
    return rx + c * dx - s * dy, ry + s * dx + c * dy, wrap(th + dth)


@dataclass
class SourceErrors:
    t: np.ndarray  # evaluation times (the source's; the fixes' for a GPS reference)
    pos_err: np.ndarray
    head_err: np.ndarray  # rad, signed (nan without a reference heading)
    dist: np.ndarray  # reference distance travelled at t
    est_x: np.ndarray  # the whole track (start-aligned for dead reckoning), for plots
    est_y: np.ndarray
    fit: tuple[float, float, float] = (0.0, 0.0, 0.0)  # best rigid fit (dx, dy, dtheta)
    pos_err_fit: np.ndarray = field(default_factory=lambda: np.zeros(0))


def rigid_fit(p: np.ndarray, q: np.ndarray) -> tuple[float, float, float]:
    """Rotation + translation (dx, dy, dtheta) minimising sum |R p + t - q|^2 (2-D Kabsch)."""
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p - pc, q - qc
    th = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(th), math.sin(th)
    t = qc - np.array([c * pc[0] - s * pc[1], s * pc[0] + c * pc[1]])
    return float(t[0]), float(t[1]), th


def apply_fit(
    fit: tuple[float, float, float], x: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    dx, dy, th = fit
    c, s = math.cos(th), math.sin(th)
    return c * x - s * y + dx, s * x + c * y + dy


def source_errors(
    name: str, track: Track, ref: Track, ref_has_heading: bool
) -> SourceErrors | None:
    """Errors of one pose source against the reference.

    With truth (dense, with heading) the truth is interpolated at the source's times; with
    GPS fixes (sparse, with gaps, no heading) the source is interpolated at the fixes'
    times. Dead-reckoning sources are first aligned at their first sample. The errors after
    the best rigid fit of the whole track to the reference are reported too (the absolute
    trajectory error of SLAM evaluations), which is what counts for a source in a frame of
    its own (SLAM against GPS).
    """
    if len(track) == 0 or len(ref) < 2:
        return None
    t, x, y, th = track.arrays()
    rt, rx, ry, rth = ref.arrays()
    if not ref_has_heading:
        rth = np.full(len(rt), np.nan)
    if name in DEAD_RECKONING:  # their own frames: align at the first sample
        q0x, q0y, q0th, ok0 = interp_pose(rt, rx, ry, rth, t[:1])
        if not ok0[0]:
            i = int(np.searchsorted(rt, t[0]))
            q0x, q0y = rx[min(i, len(rt) - 1)] * np.ones(1), ry[min(i, len(rt) - 1)] * np.ones(1)
        r0th = float(q0th[0]) if np.isfinite(q0th[0]) else 0.0
        if name == "gyro":
            th = wrap(th - th[0] + r0th)
        else:
            x, y, th = align_at_start(x, y, th, float(q0x[0]), float(q0y[0]), r0th)
    if ref_has_heading:
        qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
        if not ok.any():
            return None
        te, ex, ey, eth = t[ok], x[ok], y[ok], th[ok]
        qx, qy, qth = qx[ok], qy[ok], qth[ok]
        if name == "gyro":
            ex, ey = qx.copy(), qy.copy()
        head = wrap(eth - qth)
    else:
        ex, ey, _, ok = interp_pose(t, x, y, np.zeros(len(t)), rt)
        if ok.sum() < 2:
            return None
        te, ex, ey = rt[ok], ex[ok], ey[ok]
        qx, qy = rx[ok], ry[ok]
        head = np.full(len(te), np.nan)
    if name == "gyro":
        pos = fit_err = np.full(len(te), np.nan)
        fit = (0.0, 0.0, 0.0)
    else:
        pos = np.hypot(ex - qx, ey - qy)
        fit = rigid_fit(np.column_stack([ex, ey]), np.column_stack([qx, qy]))
        fx, fy = apply_fit(fit, ex, ey)
        fit_err = np.hypot(fx - qx, fy - qy)
    dist = np.interp(te.astype(float), rt.astype(float), path_length(rx, ry))
    dist = dist - dist[0]
    return SourceErrors(te, pos, head, dist, x, y, fit, fit_err)


def drift_per_metre(head_err: np.ndarray, dist: np.ndarray) -> dict[str, float]:
    """Heading drift in deg/m: final |error| / distance, and the LSQ slope through 0."""
    ok = np.isfinite(head_err)
    if ok.sum() < 2:
        return {}
    e, d = np.degrees(np.abs(head_err[ok])), dist[ok]
    if d[-1] <= 0.5:
        return {"distance_m": float(d[-1])}
    return {
        "distance_m": float(d[-1]),
        "final_deg_per_m": float(e[-1] / d[-1]),
        "slope_deg_per_m": float(np.dot(d, e) / np.dot(d, d)),
    }


def ekf_containment(track: Track, ref: Track, sigmas: float = 3.0) -> dict[str, float] | None:
    """Fraction of pose estimates whose ``sigmas``-sigma bounds hold the truth (per axis)."""
    if len(track.var) != len(track) or len(track) == 0 or len(ref) < 2:
        return None
    t = np.asarray(track.t, dtype=np.int64)
    order = np.argsort(t, kind="stable")
    t = t[order]
    x, y, th = (np.asarray(a)[order] for a in (track.x, track.y, track.theta))
    var = np.asarray(track.var, dtype=float)[order]
    rt, rx, ry, rth = ref.arrays()
    qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
    if not ok.any():
        return None
    sd = np.sqrt(np.clip(var, 0.0, None))
    inside = (
        (np.abs(x - qx) <= sigmas * sd[:, 0])
        & (np.abs(y - qy) <= sigmas * sd[:, 1])
        & (np.abs(wrap(th - qth)) <= sigmas * sd[:, 2])
    )
    return {"poses": int(ok.sum()), "contained_fraction": float(inside[ok].mean())}


def box_contains(box: PoseBox, x: float, y: float, theta: float) -> bool:
    """Whether the box holds (x, y, theta); theta is compared modulo 2 pi."""
    if box.x.empty or box.y.empty or box.theta.empty:
        return False
    if not (box.x.contains(x) and box.y.contains(y)):
        return False
    width = box.theta.hi - box.theta.lo
    if width >= 2.0 * math.pi:
        return True
    return (theta - box.theta.lo) % (2.0 * math.pi) <= width + 1e-12


@dataclass
class BoxSeries:
    t: np.ndarray
    area: np.ndarray
    contained: np.ndarray  # 1 contained, 0 not, -1 no truth at that time
    boxes: list[PoseBox]


def box_series(rl: RobotLog) -> BoxSeries | None:
    if not rl.boxes:
        return None
    t = np.asarray([bt for bt, _ in rl.boxes], dtype=np.int64)
    area = np.asarray([b.area_m2 for _, b in rl.boxes])
    contained = np.full(len(t), -1, dtype=int)
    if len(rl.truth) >= 2:
        rt, rx, ry, rth = rl.truth.arrays()
        qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
        for i, (_, b) in enumerate(rl.boxes):
            if ok[i]:
                contained[i] = int(box_contains(b, qx[i], qy[i], qth[i]))
    return BoxSeries(t, area, contained, [b for _, b in rl.boxes])


def box_summary(bs: BoxSeries) -> dict[str, Any]:
    judged = bs.contained >= 0
    out: dict[str, Any] = {
        "boxes": len(bs.t),
        "empty_boxes": int(sum(1 for b in bs.boxes if b.x.empty or b.y.empty or b.theta.empty)),
        "area_m2": _stats(bs.area),
        "theta_width_deg": _stats(
            np.degrees([max(0.0, b.theta.hi - b.theta.lo) for b in bs.boxes])
        ),
    }
    out["area_m2"]["median"] = float(np.median(bs.area))
    if judged.any():
        out["judged"] = int(judged.sum())
        out["contained_fraction"] = float(bs.contained[judged].mean())
        out["violations"] = int((bs.contained[judged] == 0).sum())
    return out


# ---------------------------------------------------------------------------------------
# Map quality.


def grid_of_msg(msg: OccupancyGridMsg):  # noqa: ANN201 - mapping.grid.OccupancyGrid
    """A mapping OccupancyGrid (log-odds) from a logged foxglove.Grid."""
    from mapping.export import from_grid_msg
    from mapping.grid import OccupancyGrid

    cells = from_grid_msg(msg).astype(float)
    p = np.clip(cells / 100.0, 0.005, 0.995)
    logodds = np.where(cells < 0, 0.0, np.log(p) - np.log1p(-p))
    res = msg.cell_size.x
    return OccupancyGrid.from_array(logodds, res, (msg.pose.position.x, msg.pose.position.y))


def load_plan(name: str):  # noqa: ANN201 - fakes.world.FloorPlan
    from fakes.world import floorplan

    return floorplan.load(name)


def map_summary(rl: RobotLog, plan_name: str | None) -> dict[str, Any] | None:
    if rl.last_map is None:
        return None
    grid = grid_of_msg(rl.last_map)
    cells = grid.trinary()
    out: dict[str, Any] = {
        "maps_logged": rl.maps,
        "rows": int(grid.shape[0]),
        "cols": int(grid.shape[1]),
        "resolution_m": grid.resolution,
        "known_cells": int((cells >= 0).sum()),
        "occupied_cells": int((cells == 1).sum()),
    }
    if plan_name:
        try:
            plan = load_plan(plan_name)
        except ValueError as exc:
            out["plan_error"] = str(exc)
            return out
        from mapping.quality import compare

        q = compare(grid, plan)
        out["plan"] = plan_name
        out.update({f"quality_{k}": v for k, v in q.as_dict().items()})
        out["match_ratio"] = q.match_ratio
    return out


# ---------------------------------------------------------------------------------------
# Diagnostics.


def diagnostics_summary(diags: dict[str, list[DeviceDiagnostics]]) -> dict[str, Any]:
    out = {}
    for dev in sorted(diags):
        ds = diags[dev]
        last = ds[-1]
        rates = [d.rate_hz for d in ds if d.connected]
        errors = sorted({d.last_error for d in ds if d.last_error})
        out[dev] = {
            "reports": len(ds),
            "connected_fraction": sum(d.connected for d in ds) / len(ds),
            "frames_ok": last.frames_ok,
            "bad_checksums": last.bad_checksums,
            "resyncs": last.resyncs,
            "bytes_skipped": last.bytes_skipped,
            "frames_lost": last.frames_lost,
            "reconnects": last.reconnects,
            "mean_rate_hz": float(np.mean(rates)) if rates else 0.0,
            "errors": errors[:5],
        }
    return out


# ---------------------------------------------------------------------------------------


@dataclass
class RobotAnalysis:
    """Numbers and the series the plots need, for one robot."""

    name: str
    summary: dict[str, Any]
    log: RobotLog
    errors: dict[str, SourceErrors]
    boxes: BoxSeries | None
    reference: str


def analyze_robot(rl: RobotLog, plan_name: str | None) -> RobotAnalysis:
    if len(rl.truth) >= 2:
        ref, ref_name, ref_heading = rl.truth, "truth", True
    elif len(rl.gps) >= 2:
        ref, ref_name, ref_heading = rl.gps, "gps", False
    else:
        ref, ref_name, ref_heading = Track(), "none", False
    s: dict[str, Any] = {"reference": ref_name, "topics": dict(sorted(rl.counts.items()))}
    if len(ref) >= 2:
        _, rx, ry, _ = ref.arrays()
        s["reference_distance_m"] = float(path_length(rx, ry)[-1])
    errs: dict[str, SourceErrors] = {}
    paths: dict[str, Any] = {}
    for name in sorted(rl.sources):
        tr = rl.sources[name]
        if name == "gyro" and not ref_heading:
            continue
        e = source_errors(name, tr, ref, ref_heading)
        if e is None:
            continue
        errs[name] = e
        entry: dict[str, Any] = {"samples": len(e.t)}
        if name != "gyro":
            entry["position_error_m"] = _stats(e.pos_err)
            entry["initial_position_error_m"] = float(e.pos_err[0])
            entry["position_error_after_rigid_fit_m"] = _stats(e.pos_err_fit)
            entry["rigid_fit"] = {
                "dx_m": e.fit[0],
                "dy_m": e.fit[1],
                "dtheta_deg": math.degrees(e.fit[2]),
            }
        if ref_heading:
            entry["heading_error_deg"] = _stats(np.degrees(e.head_err))
            entry["heading_drift"] = drift_per_metre(e.head_err, e.dist)
        if name in DEAD_RECKONING:
            entry["aligned_at_start"] = True
        paths[name] = entry
    if paths:
        s["paths"] = paths
    if ref_name == "truth":
        for name, tr in sorted(rl.sources.items()):
            c = ekf_containment(tr, ref)
            if c is not None:
                s.setdefault("ekf_3sigma", {})[name] = c
    bs = box_series(rl)
    if bs is not None:
        s["cp_boxes"] = box_summary(bs)
    m = map_summary(rl, plan_name)
    if m is not None:
        s["map"] = m
    if rl.landmarks is not None:
        s["landmarks"] = {"maps_logged": rl.landmark_maps, "count": len(rl.landmarks.xs)}
    if rl.diagnostics:
        s["diagnostics"] = diagnostics_summary(rl.diagnostics)
    if rl.info is not None:
        s["robot_info"] = {
            "name": rl.info.name,
            "class": rl.info.robot_class,
            "subclass": rl.info.subclass,
        }
    return RobotAnalysis(rl.name, s, rl, errs, bs, ref_name)


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


@dataclass
class Analysis:
    summary: dict[str, Any]
    robots: dict[str, RobotAnalysis]
    plan_name: str | None


def analyze(path: str | Path, plan: str | None = None) -> Analysis:
    """Analyse a log; returns the JSON-able summary and the series for the plots.

    ``plan`` overrides the floor plan named in the log's "hilnav" metadata."""
    stats = ReadStats()
    robots = load(path, stats)
    meta = read_metadata(path).get("hilnav", {})
    plan_name = plan or meta.get("plan") or None
    out: dict[str, Any] = {
        "log": str(path),
        "metadata": dict(sorted(meta.items())),
        "read": {k: v for k, v in stats.as_dict().items() if k != "errors"},
        "robots": {},
    }
    per: dict[str, RobotAnalysis] = {}
    for name in sorted(robots):
        ra = analyze_robot(robots[name], plan_name)
        per[name] = ra
        out["robots"][name] = ra.summary
    all_t = [
        tr.t for rl in robots.values() for tr in [rl.truth, rl.gps, *rl.sources.values()] if tr.t
    ]
    if all_t:
        lo = min(min(t) for t in all_t)
        hi = max(max(t) for t in all_t)
        out["duration_s"] = (hi - lo) / NS
    return Analysis(_round(out), per, plan_name)
