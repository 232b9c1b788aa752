"""Benchmark: can the IR beams that look ahead measure the wheel odometry's distance scale?

The IR map's pose error on real data is dominated by the wheels' distance error (3-8 %
over 20 m stretches on the Intel log, `bench/ir_real.py`'s true-heading row), and loop
closures cannot see an error of scale common to a whole loop. Metric evidence along the
track can: while the robot drives straight at a plane (a wall ahead), two beams that look
ahead on either side of the heading hit it at two points, which give the plane's
distance D and the angle a of its normal in the robot frame; driving a distance s moves
D by s cos a. So the slope of D over the odometry's distance is -k cos a, k the true
distance per odometry distance.

On a laser log with corrected poses (the same inputs as `bench/ir_real.py`: the beams at
the IR mounts, 1-5.5 m), this finds every stretch of at least ``--min-scans`` scans and
``--min-m`` of travel where the two forward-most beams (|yaw| <= 45 deg, at least 10 deg
apart) hit one plane (its normal within 8 deg of the first, the heading within 3 deg)
with |cos a| >= 0.7, fits D against the odometry's distance, and compares k with the
reference poses' distance per odometry distance over the same scans. A stretch is clean
when the fit's residual is below ``--clean-m``; that is not proof of one plane: two beams
on the two sides of a passage fit a line too, one that moves with the robot (k near 0).

Prints a row per stretch and, the LAST line, a JSON object (``events``,
``events_clean``, ``k_err_median_clean``: the median |k - k_reference| of the clean
ones, ``k_run``: the whole run's reference distance per odometry distance).

    python bench/odometry_scale.py DIR [--mounts "x,y,yaw_deg;..."] [--scans N]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from ir_real import find_inputs

from hilnav.config import load_config
from hilnav.importers.carmen import emulate
from mapping.carmen import load_laser_log
from numerics.angles import wrap_angle


def front_pair(mounts: np.ndarray) -> tuple[int, int] | None:
    """The two beams that look ahead (|yaw| <= 45 deg) the furthest apart (>= 10 deg)."""
    ahead = [i for i in range(len(mounts)) if abs(wrap_angle(mounts[i, 2])) <= math.radians(45)]
    best = None
    for a in ahead:
        for b in ahead:
            gap = wrap_angle(mounts[b, 2] - mounts[a, 2])
            if gap >= math.radians(10) and (best is None or gap > best[0]):
                best = (gap, a, b)
    return None if best is None else (best[1], best[2])


def plane(mounts: np.ndarray, ranges: np.ndarray, a: int, b: int) -> tuple[float, float]:
    """(D, angle of the normal) of the line through the two beams' hits, robot frame."""
    p = [mounts[i, :2] + ranges[i] * np.array([math.cos(mounts[i, 2]), math.sin(mounts[i, 2])])
         for i in (a, b)]  # fmt: skip
    d = p[1] - p[0]
    n = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9)
    dist = float(n @ p[0])
    if dist < 0:
        n, dist = -n, -dist
    return dist, math.atan2(n[1], n[0])


def travelled(xy: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def events(
    run, pair, min_scans: int, min_m: float
) -> list[tuple[int, int, float, float, float, float]]:
    """(first scan, scans, odometry m, k, k reference, fit residual m) per stretch."""
    mounts = run.mounts
    rng = np.array([s.ranges_m for s in run.scans])
    ok = np.array([[st == "ok" for st in s.status] for s in run.scans])
    odo = np.array([[o.pose.x, o.pose.y, o.pose.theta] for o in run.odometry])
    ref = np.array([[t.pose.x, t.pose.y] for t in run.truth])
    s_odo, s_ref = travelled(odo[:, :2]), travelled(ref)
    a, b = pair
    out, k, n = [], 0, len(rng)
    while k < n:
        j, dists, angles = k, [], []
        while (
            j < n
            and ok[j, a]
            and ok[j, b]
            and abs(wrap_angle(odo[j, 2] - odo[k, 2])) < math.radians(3)
        ):
            dist, ang = plane(mounts, rng[j], a, b)
            if angles and abs(wrap_angle(ang - angles[0])) > math.radians(8):
                break
            dists.append(dist)
            angles.append(ang)
            j += 1
        cos_a = math.cos(float(np.median(angles))) if angles else 0.0
        if len(dists) >= min_scans and s_odo[j - 1] - s_odo[k] >= min_m and abs(cos_a) >= 0.7:
            s = s_odo[k:j] - s_odo[k]
            fit = np.polyfit(s, np.array(dists), 1)
            resid = float(np.std(np.array(dists) - np.polyval(fit, s)))
            k_ref = (s_ref[j - 1] - s_ref[k]) / (s_odo[j - 1] - s_odo[k])
            out.append((k, j - k, float(s[-1]), -fit[0] / cos_a, float(k_ref), resid))
        k = max(j, k + 1)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path, help="folder of the laser log (or the log itself)")
    ap.add_argument("--mounts", help='IR mounts "x,y,yaw_deg;..." (default: the config\'s)')
    ap.add_argument("--scans", type=int, help="only the first N scans")
    ap.add_argument("--min-scans", type=int, default=15)
    ap.add_argument("--min-m", type=float, default=0.8)
    ap.add_argument("--clean-m", type=float, default=0.03)
    args = ap.parse_args(argv)
    from hilnav.commands.importer import parse_mounts

    cfg = load_config(None)
    mounts = np.array(parse_mounts(args.mounts) if args.mounts else cfg.geometry.ir_mounts_rad())
    src, ref_log = find_inputs(args.dir)
    log = load_laser_log(src, ref_log).head(args.scans)
    if log.reference is None:
        raise SystemExit(f"{src}: no reference poses (a corrected log is needed)")
    run = emulate(log, mounts)
    pair = front_pair(mounts)
    found = events(run, pair, args.min_scans, args.min_m) if pair else []
    print(f"{'scan':>6} {'scans':>5} {'odo m':>6} {'k':>6} {'k ref':>6} {'resid m':>7}")
    for e in found:
        print(f"{e[0]:>6} {e[1]:>5} {e[2]:6.2f} {e[3]:6.3f} {e[4]:6.3f} {e[5]:7.3f}")
    clean = [e for e in found if e[5] < args.clean_m]
    odo = np.array([[o.pose.x, o.pose.y] for o in run.odometry])
    ref = np.array([[t.pose.x, t.pose.y] for t in run.truth])
    err = [abs(e[3] - e[4]) for e in clean]
    result = {
        "bench": "odometry_scale",
        "scans": len(run.scans),
        "distance_m": round(float(travelled(ref)[-1]), 1),
        "front_pair": list(pair) if pair else None,
        "events": len(found),
        "events_clean": len(clean),
        "k_err_median_clean": round(float(np.median(err)), 4) if err else None,
        "k_run": round(float(travelled(ref)[-1] / travelled(odo)[-1]), 4),
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
