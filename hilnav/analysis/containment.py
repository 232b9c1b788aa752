"""Containment: CP pose boxes (ekf-vs-cp.txt) and EKF 3-sigma bounds against the truth.

The fraction of ``pose_box`` boxes that contain the truth and their areas; for comparison,
the fraction of EKF poses whose 3-sigma bounds hold the truth. Instants in a gap of the
truth are not judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hilnav.analysis.errors import stats
from hilnav.analysis.geometry import interp_pose
from hilnav.analysis.result import BoxContainment, BoxSummary, EkfContainment
from hilnav.analysis.tracks import RobotLog, Track
from msgs import PoseBox
from numerics.angles import wrap


def ekf_containment(track: Track, ref: Track, sigmas: float = 3.0) -> EkfContainment | None:
    """Fraction of pose estimates whose ``sigmas``-sigma bounds hold the truth (per axis)."""
    if len(track.var) != len(track) or len(track) == 0 or len(ref) < 2:
        return None
    t = np.asarray(track.t, dtype=np.int64)
    order = np.argsort(t, kind="stable")
    t = t[order]
    x, y, th = (np.asarray(a)[order] for a in (track.x, track.y, track.theta))
    var = np.asarray(track.var, dtype=float)[order]
    if not np.isfinite(var).all():
        return None  # a heading estimate: no position variance (consistency.py judges it)
    rt, rx, ry, rth = ref.arrays()
    qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
    ok &= ref.covered(t)
    if not ok.any():
        return None
    sd = np.sqrt(np.clip(var, 0.0, None))
    inside = (
        (np.abs(x - qx) <= sigmas * sd[:, 0])
        & (np.abs(y - qy) <= sigmas * sd[:, 1])
        & (np.abs(wrap(th - qth)) <= sigmas * sd[:, 2])
    )
    return EkfContainment(poses=int(ok.sum()), contained_fraction=float(inside[ok].mean()))


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
    """The CP boxes of a robot over time, each judged against the truth when there is one."""

    t: np.ndarray
    area: np.ndarray
    contained: np.ndarray  # 1 contained, 0 not, -1 no truth at that time
    boxes: list[PoseBox]


def box_series(rl: RobotLog) -> BoxSeries | None:
    """The robot's boxes, their areas, and whether each holds the interpolated truth."""
    if not rl.boxes:
        return None
    t = np.asarray([bt for bt, _ in rl.boxes], dtype=np.int64)
    area = np.asarray([b.area_m2 for _, b in rl.boxes])
    contained = np.full(len(t), -1, dtype=int)
    if len(rl.truth) >= 2:
        rt, rx, ry, rth = rl.truth.arrays()
        qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
        ok &= rl.truth.covered(t)
        for i, (_, b) in enumerate(rl.boxes):
            if ok[i]:
                contained[i] = int(box_contains(b, qx[i], qy[i], qth[i]))
    return BoxSeries(t, area, contained, [b for _, b in rl.boxes])


def box_summary(bs: BoxSeries) -> BoxSummary:
    """Count, areas, heading widths and containment of a robot's boxes."""
    judged = bs.contained >= 0
    containment = None
    if judged.any():
        containment = BoxContainment(
            judged=int(judged.sum()),
            contained_fraction=float(bs.contained[judged].mean()),
            violations=int((bs.contained[judged] == 0).sum()),
            median_area_m2=float(np.median(bs.area[judged])),
        )
    widths = np.degrees([max(0.0, b.theta.hi - b.theta.lo) for b in bs.boxes])
    return BoxSummary(
        boxes=len(bs.t),
        empty_boxes=int(sum(1 for b in bs.boxes if b.x.empty or b.y.empty or b.theta.empty)),
        area_m2=stats(bs.area),
        median_area_m2=float(np.median(bs.area)),
        theta_width_deg=stats(widths),
        containment=containment,
    )
