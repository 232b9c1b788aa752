"""A small synthetic robot log with known errors, written with LogWriter (for log tests)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fakes.world import floorplan
from hilnav.log.writer import LogWriter
from mapping.export import to_grid_msg
from mapping.grid import OccupancyGrid
from msgs import (
    DeviceDiagnostics,
    GpsFix,
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    Interval,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RawBytes,
    RobotOdometry,
)

T0 = 1_000_000_000_000
ODO_DRIFT_DEG_PER_M = 3.0
HEADING_DRIFT_DEG_PER_M = 0.5
POSE_OFFSET_M = 0.1
BOX_HALF_M = 0.2
BAD_BOXES = (5, 11)
FLIPPED_CELLS = 200


def truth_path(speed: float = 0.3, rate_hz: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, (N, 3) poses) of a rectangle loop in the office's west room, with turns in place."""
    corners = [(1.5, 1.5), (3.0, 1.5), (3.0, 4.0), (1.5, 4.0), (1.5, 1.5)]
    dt = 1.0 / rate_hz
    poses: list[tuple[float, float, float]] = []
    for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:], strict=True):
        th = math.atan2(y1 - y0, x1 - x0)
        n = int(round(math.hypot(x1 - x0, y1 - y0) / (speed * dt)))
        for i in range(n):
            f = i / n
            poses.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0), th))
    poses.append((1.5, 1.5, -math.pi / 2))
    p = np.asarray(poses)
    return np.arange(len(p)) * dt, p


def write_synthetic_log(
    path: Path, seed: int = 0, with_map: bool = True, with_truth: bool = True
) -> dict:
    """Write the log; return what the analysis should find."""
    rng = np.random.default_rng(seed)
    t_s, truth = truth_path()
    dist = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(truth[:, 0]), np.diff(truth[:, 1])))])
    k_odo = math.radians(ODO_DRIFT_DEG_PER_M)
    k_head = math.radians(HEADING_DRIFT_DEG_PER_M)
    th_unwrapped = np.unwrap(truth[:, 2])
    expected: dict = {"distance_m": float(dist[-1]), "n": len(t_s)}
    meta = {"robot": "r1", "plan": "office", "seed": str(seed), "config": "synthetic"}
    with LogWriter(path, metadata=meta, wall_clock=False) as w:
        ox = oy = 0.0
        sigmas = []
        for i, ts in enumerate(t_s):
            t = T0 + int(round(ts * 1e9))
            x, y, th = truth[i]
            if with_truth:
                w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(x, y, th)), t)
            # Odometry in its own frame with a heading drift of k_odo per metre.
            th_odo = th_unwrapped[i] - th_unwrapped[0] + k_odo * dist[i]
            if i > 0:
                dd = dist[i] - dist[i - 1]
                ox += dd * math.cos(th_odo)
                oy += dd * math.sin(th_odo)
            to = t + 20_000_000  # 20 ms after the truth: interpolated
            odo = RobotOdometry(
                to,
                Pose2D(ox, oy, math.remainder(th_odo, 2 * math.pi)),
                0.3,
                0.3,
                0.3,
                0.0,
                12.0,
                True,
                True,
            )
            w.write("/r1/odometry", odo, to)
            th_gyro = th_unwrapped[i] + 0.2  # gyro angle: offset, no drift
            w.write("/r1/gyro", GyroSample(to, 0.0, th_gyro), to)
            th_h = th_unwrapped[i] + k_head * dist[i]
            hp = Pose2D(x - truth[0, 0], y - truth[0, 1], math.remainder(th_h, 2 * math.pi))
            w.write("/r1/heading", HeadingEstimate(to, hp.theta, 1e-4, hp), to)
            # Pose EKF: constant offset along x; sigma 0.05 on odd samples, 0.01 on even ones.
            sig = 0.05 if i % 2 else 0.01
            sigmas.append(sig)
            cov = (sig**2, 0, 0, 0, sig**2, 0, 0, 0, 0.01)
            w.write("/r1/pose", PoseEstimate(t, Pose2D(x + POSE_OFFSET_M, y, th), cov), t)
            w.write("/r1/raw/arcos", RawBytes(t, "arcos", b"\xfa\xfb\x03"), t)
            if i % 10 == 0:
                gx, gy = x + rng.normal(0, 0.5), y + rng.normal(0, 0.5)
                w.write("/r1/gps", GpsFix(t, mode=2, east_m=gx, north_m=gy), t)
                diag = DeviceDiagnostics(
                    t, "arcos", True, frames_ok=i, bad_checksums=3, rate_hz=10.0
                )
                w.write("/r1/diagnostics", diag, t)
            if i % 5 == 0:
                j = i // 5
                bx = x + (1.0 if j in BAD_BOXES else 0.0)
                box = PoseBox(
                    t,
                    "r1",
                    Interval(bx - BOX_HALF_M, bx + BOX_HALF_M),
                    Interval(y - BOX_HALF_M, y + BOX_HALF_M),
                    Interval(th - 0.1, th + 0.1),
                )
                w.write("/r1/pose_box", box, t)
        expected["boxes"] = len(range(0, len(t_s), 5))
        expected["bad_boxes"] = len(BAD_BOXES)
        expected["ekf_contained"] = float(np.mean([3 * s >= POSE_OFFSET_M for s in sigmas]))
        if with_map:
            plan = floorplan.load("office")
            grid = OccupancyGrid.from_array(np.zeros((150, 190)), 0.05, (-0.25, -0.25))
            raster = plan.rasterize(grid.resolution, grid.origin, grid.shape)
            cells = raster.astype(float).copy()
            known = np.flatnonzero(raster.ravel() >= 0)
            flip = rng.choice(known, size=FLIPPED_CELLS, replace=False)
            flat = cells.ravel()
            flat[flip] = 1 - flat[flip]
            p = np.where(cells > 0.5, 0.9, 0.1)
            grid.logodds = np.where(raster >= 0, np.log(p / (1 - p)), 0.0).astype(np.float32)
            t_end = T0 + int(round(t_s[-1] * 1e9))
            w.write("/r1/map", to_grid_msg(grid, t_end), t_end)
            expected["match_ratio"] = 1.0 - FLIPPED_CELLS / len(known)
    return expected
