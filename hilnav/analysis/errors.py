"""Errors of each pose source against the reference (truth, else GPS), and heading drift.

- **path error** of every pose source — ``pose`` (pose EKF), ``heading`` (heading filter's
  dead reckoning), ``odometry`` (raw ARCOS odometry), ... — against the truth
  interpolated in time, or against the GPS fixes as ``gps_error`` defines it (the
  source's latest pose at each fix kept by the outlier rule); dead-reckoning sources are
  aligned to the reference at their first sample, and errors after the best rigid fit of
  the whole track are given too; against the truth, the mean error of the track's motions
  over 10 m of travel as well (``geometry.relative_error``: what it gets wrong locally).
- **heading drift per metre** (ir-grid-mapping.txt, eq. 2: encoders drift by about
  alpha = 3 deg/m): final |heading error| over the distance travelled, and the
  least-squares slope of |heading error| against distance; also for the gyro's integrated
  angle (aligned at its first sample).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hilnav.analysis.geometry import (
    align_at_start,
    apply_fit,
    interp_pose,
    path_length,
    relative_error,
    rigid_fit,
)
from hilnav.analysis.gps_error import errors_at_fixes
from hilnav.analysis.result import (
    HeadingDrift,
    HeadingErrors,
    PositionErrors,
    RigidFit,
    SourceTrack,
    Stats,
)
from hilnav.analysis.tracks import DEAD_RECKONING, Track
from numerics.angles import wrap

RELATIVE_M = 10.0  # the relative error's distance of travel


def stats(e: np.ndarray) -> Stats | None:
    """Mean, RMS, p95, max and last of |e| over its finite values (None when there are none)."""
    e = np.abs(e[np.isfinite(e)])
    if e.size == 0:
        return None
    return Stats(
        mean=float(e.mean()),
        rms=float(np.sqrt(np.mean(e**2))),
        p95=float(np.percentile(e, 95)),
        max=float(e.max()),
        final=float(e[-1]),
    )


@dataclass
class SourceErrors:
    """The error series of one pose source (for the figures and the plots)."""

    t: np.ndarray  # evaluation times (the source's; the fixes' for a GPS reference)
    pos_err: np.ndarray
    head_err: np.ndarray  # rad, signed (nan without a reference heading)
    dist: np.ndarray  # reference distance travelled at t
    est_x: np.ndarray  # the whole track (start-aligned for dead reckoning), for plots
    est_y: np.ndarray
    fit: tuple[float, float, float] = (0.0, 0.0, 0.0)  # best rigid fit (dx, dy, dtheta)
    pos_err_fit: np.ndarray = field(default_factory=lambda: np.zeros(0))
    relative_10m: float = math.nan  # mean error of the motions over 10 m (truth only)


def source_errors(
    name: str, track: Track, ref: Track, ref_has_heading: bool, keep: np.ndarray | None = None
) -> SourceErrors | None:
    """Errors of one pose source against the reference.

    With truth (dense, with heading) the truth is interpolated at the source's times; with
    GPS fixes (sparse, with gaps, no heading) the errors are those of
    :mod:`hilnav.analysis.gps_error` at the fixes ``keep`` keeps (None: all). Dead-reckoning
    sources are first aligned at their first sample. The errors after the best rigid fit of
    the whole track to the reference are reported too (the absolute trajectory error of
    SLAM evaluations), which is what counts for a source in a frame of its own (SLAM
    against GPS).
    """
    if len(track) == 0 or len(ref) < 2:
        return None
    t, x, y, th = track.arrays()
    rt, rx, ry, rth = ref.arrays()
    if not ref_has_heading:
        rth = np.full(len(rt), np.nan)
    if name in DEAD_RECKONING:  # their own frames: align at the first sample
        q0x, q0y, q0th, ok0 = interp_pose(rt, rx, ry, rth, t[:1])
        ok0 &= ref.covered(t[:1])
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
        ok &= ref.covered(t)  # no score inside a gap of the truth
        if not ok.any():
            return None
        te, ex, ey, eth = t[ok], x[ok], y[ok], th[ok]
        qx, qy, qth = qx[ok], qy[ok], qth[ok]
        if name == "gyro":
            ex, ey = qx.copy(), qy.copy()
        head = wrap(eth - qth)
    else:
        ge = errors_at_fixes(t, x, y, rt, rx, ry, keep)
        if ge is None:
            return None
        te = rt[ge.used]
        dist = np.interp(te.astype(float), rt.astype(float), path_length(rx, ry))
        head = np.full(len(te), np.nan)
        return SourceErrors(te, ge.error, head, dist - dist[0], x, y, ge.fit, ge.error_fit)
    rel = math.nan
    if name == "gyro":
        pos = fit_err = np.full(len(te), np.nan)
        fit = (0.0, 0.0, 0.0)
    else:
        pos = np.hypot(ex - qx, ey - qy)
        fit = rigid_fit(np.column_stack([ex, ey]), np.column_stack([qx, qy]))
        fx, fy = apply_fit(fit, ex, ey)
        fit_err = np.hypot(fx - qx, fy - qy)
        if np.all(np.isfinite(eth)) and np.all(np.isfinite(qth)):
            rel = relative_error(np.column_stack([ex, ey, eth]), np.column_stack([qx, qy, qth]),
                                 RELATIVE_M)  # fmt: skip
    dist = np.interp(te.astype(float), rt.astype(float), path_length(rx, ry))
    dist = dist - dist[0]
    return SourceErrors(te, pos, head, dist, x, y, fit, fit_err, rel)


def drift_per_metre(head_err: np.ndarray, dist: np.ndarray) -> HeadingDrift | None:
    """Heading drift in deg/m: final |error| / distance, and the LSQ slope through 0."""
    ok = np.isfinite(head_err)
    if ok.sum() < 2:
        return None
    e, d = np.degrees(np.abs(head_err[ok])), dist[ok]
    if d[-1] <= 0.5:
        return HeadingDrift(distance_m=float(d[-1]))
    return HeadingDrift(
        distance_m=float(d[-1]),
        final_deg_per_m=float(e[-1] / d[-1]),
        slope_deg_per_m=float(np.dot(d, e) / np.dot(d, d)),
    )


def source_track(name: str, e: SourceErrors, ref_has_heading: bool) -> SourceTrack:
    """The figures of one source's errors (no position for the gyro, no heading on GPS)."""
    position = None
    if name != "gyro":
        fit = RigidFit(dx_m=e.fit[0], dy_m=e.fit[1], dtheta_deg=math.degrees(e.fit[2]))
        position = PositionErrors(
            error_m=stats(e.pos_err),
            initial_m=float(e.pos_err[0]),
            after_rigid_fit_m=stats(e.pos_err_fit),
            rigid_fit=fit,
            relative_10m_m=e.relative_10m if math.isfinite(e.relative_10m) else None,
        )
    heading = None
    if ref_has_heading:
        heading = HeadingErrors(
            error_deg=stats(np.degrees(e.head_err)), drift=drift_per_metre(e.head_err, e.dist)
        )
    return SourceTrack(len(e.t), position, heading, aligned_at_start=name in DEAD_RECKONING)
