"""Test helper: a Pioneer with six IR sensors driving loops in the paper's 7 x 7 m room.

The true path is kinematic (straight legs, turns on the spot, one pose per 3.5 cm); the IR
scans come from the fakes' error model (curve with near-range ambiguity, voltage noise,
dropouts, 10-bit ADC) read back through the driver's curve. ``drifted`` integrates the
true increments with the heading increments scaled (a gyro scale error, the dominant
heading drift of a cheap gyro) and a heading variance growing like a heading filter's.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.sharp import STATUS_NAMES
from fakes.world import IrErrorModel, load
from msgs import HeadingEstimate, IrScan, Pose2D

D = math.pi / 180.0
MOUNTS = np.array(
    [
        [0.20, 0.06, 10 * D],
        [0.20, -0.06, -10 * D],
        [0.16, 0.14, 45 * D],
        [0.16, -0.14, -45 * D],
        [0.02, 0.19, 90 * D],
        [0.02, -0.19, -90 * D],
    ]
)
LOOP = [(5.4, 1.5), (5.4, 5.1), (2.2, 5.1), (1.5, 4.4), (1.5, 1.5)]


def truth_path(distance_m: float, step_m: float = 0.035, turn_rad: float = 6 * D) -> np.ndarray:
    """(N, 3) true poses along the room's loop, starting at (1.5, 1.5) facing east."""
    x, y, th = 1.5, 1.5, 0.0
    poses = [(x, y, th)]
    travelled, i = 0.0, 0
    while travelled < distance_m:
        tx, ty = LOOP[i % len(LOOP)]
        goal = math.atan2(ty - y, tx - x)
        while (e := math.remainder(goal - th, 2 * math.pi)) != 0.0:
            th += max(-turn_rad, min(turn_rad, e))
            poses.append((x, y, th))
        dist = math.hypot(tx - x, ty - y)
        n = max(1, int(dist / step_m))
        for _ in range(n):
            x += dist / n * math.cos(th)
            y += dist / n * math.sin(th)
            travelled += dist / n
            poses.append((x, y, th))
        i += 1
    return np.array(poses)


def ir_scans(poses: np.ndarray, seed: int) -> list[IrScan]:
    """One IrScan per pose, as the IR driver would report it."""
    plan = load("paper_room")
    ir = IrErrorModel()
    rng = np.random.default_rng(seed)
    out = []
    for k, (x, y, th) in enumerate(poses):
        c, s = math.cos(th), math.sin(th)
        ox = x + c * MOUNTS[:, 0] - s * MOUNTS[:, 1]
        oy = y + s * MOUNTS[:, 0] + c * MOUNTS[:, 1]
        true_r = plan.cast(np.stack([ox, oy], 1), th + MOUNTS[:, 2], 12.0)
        volts = ir.volts(ir.counts(true_r, rng))
        ranges, status = ir.curve.range(volts)
        out.append(
            IrScan(
                k * 100_000_000,
                0,
                k,
                tuple(float(r) for r in ranges),
                tuple(STATUS_NAMES[int(q)] for q in status),  # type: ignore[misc]
                tuple(float(v) for v in volts),
            )
        )
    return out


def drifted(
    poses: np.ndarray,
    heading_scale: float,
    var_per_rad: float = 0.03**2,
    var_per_m: float = 0.01**2,
    scale_sigma: float = 0.05,
) -> list[HeadingEstimate]:
    """Heading estimates (with their implied pose) whose turns are scaled by heading_scale;
    the variance is an honest filter's (fusion.heading): random growth per radian and per
    metre, plus a scale error of sigma ``scale_sigma`` on the signed sum of the turns."""
    est = poses[0].astype(float).copy()
    var = (0.5 * D) ** 2
    turned = 0.0
    out = [HeadingEstimate(0, float(est[2]), var, Pose2D(*map(float, est)))]
    for k in range(1, len(poses)):
        a, b = poses[k - 1], poses[k]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0] - a[0], b[1] - a[1]
        fx, fy = c * dx + s * dy, -s * dx + c * dy
        dth = math.remainder(b[2] - a[2], 2 * math.pi) * heading_scale
        mid = est[2] + 0.5 * dth
        est = np.array(
            [
                est[0] + fx * math.cos(mid) - fy * math.sin(mid),
                est[1] + fx * math.sin(mid) + fy * math.cos(mid),
                est[2] + dth,
            ]
        )
        var += var_per_rad * abs(dth) + var_per_m * math.hypot(fx, fy)
        turned += dth
        th = math.remainder(est[2], 2 * math.pi)
        v = var + (scale_sigma * turned) ** 2
        out.append(HeadingEstimate(k * 100_000_000, th, v, Pose2D(est[0], est[1], th)))
    return out
