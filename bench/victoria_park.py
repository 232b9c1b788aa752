"""Benchmark: EKF-SLAM (mapping.slam, slam-ekf.txt §3-5) on the whole Victoria Park data set.

Input: dead reckoning at 40 Hz (encoder speed at the rear left wheel, steering) and the
tree detections of each laser scan (range, bearing 0..pi with pi/2 ahead). GPS is used
ONLY for evaluation: the estimated laser path (the laser is the GPS antenna's position,
car.bmp) is sampled at the GPS times and compared with the GPS fixes after the best
rigid 2-D alignment (Kabsch/Umeyama without scale).

GPS outlier rule (independent of the estimate): the encoder says how far the car
travelled between two fixes; two fixes cannot be farther apart than that path length
plus a 1.5 m allowance. A fix is an outlier if it violates this bound with more than
half of its neighbours within +-10 s (at least 4 neighbours needed; fixes with fewer
neighbours, i.e. isolated in the receiver's gaps, are kept).

Vehicle geometry (a, b, H, L) is chosen by comparison with GPS: ``--geometry`` picks
one of the variants below; ``--compare`` runs the dead reckoning alone AND the SLAM with
every variant and prints each figure (the evidence for the choice, see README).

Prints a last-line JSON object: ate_rmse_m, max_err_m, landmarks, seconds,
realtime_factor (1549 s / seconds), plus gps_fixes_used/excluded and counters. Writes
a PNG of the path, the GPS and the landmarks to --out (default bench/out/).

    python bench/victoria_park.py [--data DIR] [--association nn|jcbb] [--compare]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

# One BLAS thread: the per-scan matrices are small (N < 1000) and a 2-core machine shared
# with other work makes OpenBLAS's threads spin; single-threaded is ~10x faster here.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mapping.slam.models import AckermannGeometry, AckermannModel  # noqa: E402
from mapping.slam.service import LandmarkSlam, SlamConfig  # noqa: E402
from mapping.slam.victoria_park import (  # noqa: E402
    DURATION_S,
    VictoriaParkData,
    load_victoria_park,
)

ROOT = Path(__file__).resolve().parents[1]

#: Candidate geometries: (a from the rear axle, b, H, L).
GEOMETRIES = {
    # car.bmp: the laser is a = 0.95 m AHEAD OF THE FRONT AXLE -> L + a from the rear axle;
    # encoder on the rear left wheel H = 0.76 m left of the centre line.
    "drawing": AckermannGeometry(2.83, 2.83 + 0.95, 0.5, 0.76),
    # a read as measured from the rear axle.
    "a_from_rear": AckermannGeometry(2.83, 0.95, 0.5, 0.76),
    # no encoder-to-centre speed conversion.
    "no_H": AckermannGeometry(2.83, 2.83 + 0.95, 0.5, 0.0),
    # laser on the centre line.
    "no_b": AckermannGeometry(2.83, 2.83 + 0.95, 0.0, 0.76),
}

BASE = SlamConfig(
    vehicle="ackermann",
    sigma_speed_mps=0.5,
    sigma_steer_rad=np.deg2rad(3.0),
    sigma_range_m=0.5,
    sigma_bearing_rad=np.deg2rad(1.0),
    min_range_m=1.0,
    max_range_m=40.0,
    confirm_after=3,
    initial_sigma=(1e-3, 1e-3, 1e-3),
)


def _find_data() -> Path:
    for parent in [ROOT, *ROOT.parents]:
        d = parent / "shared" / "data" / "victoria_park"
        if d.is_dir():
            return d
    return ROOT.parent / "shared" / "data" / "victoria_park"


def run_slam(
    data: VictoriaParkData, config: SlamConfig, use_scans: bool = True
) -> tuple[np.ndarray, np.ndarray, LandmarkSlam]:
    """Run the filter through the data set in time order; return (times (T,), laser
    poses (T, 3) after every event, the service)."""
    slam = LandmarkSlam(config)
    t_dr = np.round(data.dr_time_s * 1e9).astype(np.int64)
    t_sc = np.round(data.scan_time_s * 1e9).astype(np.int64)
    n_dr, n_sc = len(t_dr), len(t_sc)
    times = np.concatenate([t_dr, t_sc])
    kind = np.concatenate([np.zeros(n_dr, int), np.ones(n_sc, int)])
    index = np.concatenate([np.arange(n_dr), np.arange(n_sc)])
    order = np.lexsort((kind, times))  # controls first at equal stamps
    poses = np.empty((len(order), 3))
    speed, steer = data.speed_mps, data.steering_rad
    ekf = slam.ekf
    for row, e in enumerate(order):
        i = index[e]
        if kind[e] == 0:
            slam.control(int(times[e]), float(speed[i]), float(steer[i]))
        elif use_scans:
            z = data.scans[i]
            slam.scan(int(times[e]), z[:2].T)
        poses[row] = ekf._x[:3]
    return times[order] * 1e-9, poses, slam


def gps_inliers(data: VictoriaParkData, window_s: float = 10.0, slack_m: float = 1.5) -> np.ndarray:
    """The documented outlier rule (module docstring): boolean mask of kept fixes."""
    t, x, y = data.gps_time_s, data.gps_x_m, data.gps_y_m
    dt = np.diff(data.dr_time_s, append=data.dr_time_s[-1])
    travelled = np.concatenate([[0.0], np.cumsum(np.abs(data.speed_mps[:-1]) * dt[:-1])])
    s = np.interp(t, data.dr_time_s, travelled)
    keep = np.ones(len(t), dtype=bool)
    lo = np.searchsorted(t, t - window_s)
    hi = np.searchsorted(t, t + window_s, side="right")
    for i in range(len(t)):
        j = np.r_[lo[i] : i, i + 1 : hi[i]]
        if len(j) < 4:
            continue
        dist = np.hypot(x[j] - x[i], y[j] - y[i])
        bad = dist > np.abs(s[j] - s[i]) + slack_m
        keep[i] = np.count_nonzero(bad) <= len(j) // 2
    return keep


def rigid_align(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (2x2) and translation t minimising sum |R src + t - dst|^2."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    h = (src - mu_s).T @ (dst - mu_d)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return r, mu_d - r @ mu_s


def evaluate(
    data: VictoriaParkData, times: np.ndarray, poses: np.ndarray, keep: np.ndarray
) -> dict[str, float]:
    """ATE against the kept GPS fixes within the run's time span."""
    t = data.gps_time_s
    inside = keep & (t >= times[0]) & (t <= times[-1])
    # the latest pose at or before each fix time (the filter's estimate then)
    k = np.searchsorted(times, t[inside], side="right") - 1
    est = poses[np.maximum(k, 0), :2]
    gps = np.stack([data.gps_x_m[inside], data.gps_y_m[inside]], 1)
    r, tr = rigid_align(est, gps)
    err = np.linalg.norm(est @ r.T + tr - gps, axis=1)
    return {
        "ate_rmse_m": float(np.sqrt(np.mean(err**2))),
        "max_err_m": float(err.max()),
        "median_err_m": float(np.median(err)),
        "gps_fixes_used": int(inside.sum()),
        "rotation_rad": float(np.arctan2(r[1, 0], r[0, 0])),
        "_r": r,
        "_t": tr,
    }


def plot(
    path: Path,
    data: VictoriaParkData,
    poses: np.ndarray,
    landmarks: np.ndarray,
    keep: np.ndarray,
    ev: dict,
    title: str,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r, t = ev["_r"], ev["_t"]
    p = poses[:, :2] @ r.T + t
    lm = landmarks @ r.T + t if len(landmarks) else landmarks.reshape(0, 2)
    fig, ax = plt.subplots(figsize=(9, 9), dpi=110)
    ax.plot(data.gps_x_m[keep], data.gps_y_m[keep], ".", ms=2, color="tab:red", label="GPS")
    ax.plot(
        data.gps_x_m[~keep],
        data.gps_y_m[~keep],
        "x",
        ms=4,
        color="tab:orange",
        label="GPS outliers (excluded)",
    )
    ax.plot(p[:, 0], p[:, 1], "-", lw=0.7, color="tab:blue", label="EKF-SLAM laser path")
    if len(lm):
        ax.plot(lm[:, 0], lm[:, 1], "+", ms=4, color="tab:green", label="landmarks (trees)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def dead_reckoning_ate(data: VictoriaParkData, geometry: AckermannGeometry, keep) -> dict:
    """Dead reckoning only (same model, no scans) against GPS: a geometry check."""
    model = AckermannModel(geometry)
    x = np.zeros(3)
    poses = np.empty((len(data.dr_time_s), 3))
    dt = np.diff(data.dr_time_s, append=data.dr_time_s[-1])
    for i in range(len(dt)):
        poses[i] = x
        x, _, _ = model.predict(x, np.array([data.speed_mps[i], data.steering_rad[i]]), dt[i])
    return evaluate(data, data.dr_time_s, poses, keep)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=_find_data())
    ap.add_argument("--geometry", choices=sorted(GEOMETRIES), default="drawing")
    ap.add_argument("--association", choices=["nn", "jcbb"], default="nn")
    ap.add_argument("--compare", action="store_true", help="also run every geometry variant")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "out")
    args = ap.parse_args(argv)

    data = load_victoria_park(args.data)
    keep = gps_inliers(data)
    print(f"GPS: {len(keep)} fixes, {int((~keep).sum())} excluded as outliers")
    results = {}
    if args.compare:
        for name, geom in GEOMETRIES.items():
            dr = dead_reckoning_ate(data, geom, keep)
            cfg = replace(BASE, geometry=geom, association=args.association)
            times, poses, slam = run_slam(data, cfg)
            ev = evaluate(data, times, poses, keep)
            results[name] = {
                "dr_ate_rmse_m": round(dr["ate_rmse_m"], 2),
                "slam_ate_rmse_m": round(ev["ate_rmse_m"], 2),
                "slam_max_err_m": round(ev["max_err_m"], 2),
                "landmarks": slam.ekf.n_landmarks,
            }
            print(f"geometry {name:12s} {geom}: {results[name]}")

    cfg = replace(BASE, geometry=GEOMETRIES[args.geometry], association=args.association)
    t0 = time.perf_counter()
    times, poses, slam = run_slam(data, cfg)
    seconds = time.perf_counter() - t0
    ev = evaluate(data, times, poses, keep)
    st = slam.stats
    png = args.out / f"victoria_park_{args.association}.png"
    plot(
        png,
        data,
        poses,
        slam.ekf.landmarks,
        keep,
        ev,
        f"Victoria Park EKF-SLAM ({args.association}, geometry {args.geometry}): "
        f"ATE {ev['ate_rmse_m']:.2f} m RMS, max {ev['max_err_m']:.2f} m, "
        f"{slam.ekf.n_landmarks} landmarks",
    )
    print(f"wrote {png}")
    out = {
        "ate_rmse_m": round(ev["ate_rmse_m"], 3),
        "max_err_m": round(ev["max_err_m"], 3),
        "median_err_m": round(ev["median_err_m"], 3),
        "landmarks": slam.ekf.n_landmarks,
        "seconds": round(seconds, 2),
        "realtime_factor": round(DURATION_S / seconds, 1),
        "association": args.association,
        "geometry": args.geometry,
        "gps_fixes_used": ev["gps_fixes_used"],
        "gps_fixes_excluded": int((~keep).sum()),
        "scans": st.scans,
        "observations": st.observations,
        "matched": st.matched,
        "ambiguous": st.ambiguous,
        "tentative_expired": slam.tentative.expired,
    }
    if results:
        out["compare"] = results
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
