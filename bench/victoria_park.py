"""Benchmark: EKF-SLAM (mapping.slam, slam-ekf.txt §3-5) on the whole Victoria Park data set.

Input: dead reckoning at 40 Hz (encoder speed at the rear left wheel, steering) and the
tree detections of each laser scan (range, bearing 0..pi with pi/2 ahead). GPS is used
ONLY for evaluation: the estimated laser path (the laser is the GPS antenna's position,
car.bmp) is compared with the GPS fixes after the best rigid 2-D alignment, with the GPS
outlier rule and the error defined once in ``hilnav.analysis.gps_error`` (which
``hilnav analyze`` uses too): the latest pose at or before each kept fix, the RMS of the
distances after the rigid fit.

Vehicle geometry (a, b, H, L) is chosen by comparison with GPS: ``--geometry`` picks
one of the variants below; ``--compare`` runs the dead reckoning alone AND the SLAM with
every variant and prints each figure (the evidence for the choice, see README).

Prints a last-line JSON object: ate_rmse_m, max_err_m, landmarks, seconds,
realtime_factor (1549 s / seconds), plus gps_fixes_used/excluded and counters. Writes
a PNG of the path, the GPS and the landmarks to --out (default bench/out/).

    python bench/victoria_park.py [--data DIR] [--association nn|jcbb] [--compare]
        [--repeat N] [--baseline OLD_CHECKOUT]
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

from bench.baseline import run_baseline  # noqa: E402
from hilnav.analysis.geometry import apply_fit, rigid_fit  # noqa: E402
from hilnav.analysis.gps_error import (  # noqa: E402
    errors_at_fixes,
    gps_inliers,
    travelled_from_speed,
)
from mapping.slam.models import AckermannGeometry  # noqa: E402
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
    # H fitted to the windowed dead reckoning (best 60 s DR against GPS, see README).
    "H_fit": AckermannGeometry(2.83, 2.83 + 0.95, 0.5, 1.3),
}

BASE = SlamConfig(
    vehicle="ackermann",
    sigma_speed_mps=0.5,
    sigma_steer_rad=np.deg2rad(3.0),
    sigma_range_m=0.5,
    # 3 deg: the tree centre comes from a few 0.5 deg beams on a pitching car (sweep in
    # the README: 1 deg -> 2.77 m ATE, 2 deg -> 2.46 m, 3 deg -> 1.94 m, 5 deg -> 2.70 m)
    sigma_bearing_rad=np.deg2rad(3.0),
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
    data: VictoriaParkData, config: SlamConfig, max_landmarks: int | None = None
) -> tuple[np.ndarray, np.ndarray, LandmarkSlam]:
    """Run the filter through the data set in time order; return (times (T,), laser
    poses (T, 3) after every event, the service). With ``max_landmarks`` the run stops
    early (times/poses truncated) once the map grows past it: a diverged filter."""
    slam = LandmarkSlam(config)
    t_dr = np.round(data.dr_time_s * 1e9).astype(np.int64)
    t_sc = np.round(data.scan_time_s * 1e9).astype(np.int64)
    n_dr, n_sc = len(t_dr), len(t_sc)
    times = np.concatenate([t_dr, t_sc])
    kind = np.concatenate([np.zeros(n_dr, int), np.ones(n_sc, int)])
    index = np.concatenate([np.arange(n_dr), np.arange(n_sc)])
    order = np.lexsort((kind, times))  # controls first at equal stamps
    poses: list[tuple[float, float, float]] = []
    speed, steer = data.speed_mps.tolist(), data.steering_rad.tolist()
    ekf = slam.ekf
    events = zip(times[order].tolist(), kind[order].tolist(), index[order].tolist(), strict=True)
    for row, (t, k, i) in enumerate(events):
        if k == 0:
            slam.control(t, speed[i], steer[i])
        else:
            z = data.scans[i]
            slam.scan(t, z[:2].T)
            if max_landmarks is not None and ekf.n_landmarks > max_landmarks:
                poses.append(ekf.pose)
                return times[order][: row + 1] * 1e-9, np.array(poses), slam
        poses.append(ekf.pose)
    return times[order] * 1e-9, np.array(poses), slam


def gps_keep(data: VictoriaParkData) -> np.ndarray:
    """The fixes kept by the GPS outlier rule (hilnav.analysis.gps_error), the distance
    travelled being the encoder's."""
    travel = travelled_from_speed(data.dr_time_s, data.speed_mps)
    return gps_inliers(data.gps_time_s, data.gps_x_m, data.gps_y_m, data.dr_time_s, travel)


def evaluate(
    data: VictoriaParkData, times: np.ndarray, poses: np.ndarray, keep: np.ndarray
) -> dict[str, float]:
    """ATE against the kept GPS fixes within the run's time span (hilnav.analysis.gps_error)."""
    ge = errors_at_fixes(
        times, poses[:, 0], poses[:, 1], data.gps_time_s, data.gps_x_m, data.gps_y_m, keep
    )
    if ge is None:
        raise ValueError("fewer than two GPS fixes within the run")
    return {
        "ate_rmse_m": ge.ate_rmse_m,
        "max_err_m": float(ge.error_fit.max()),
        "median_err_m": float(np.median(ge.error_fit)),
        "gps_fixes_used": len(ge.used),
        "rotation_rad": ge.fit[2],
        "_fit": ge.fit,
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

    p = np.column_stack(apply_fit(ev["_fit"], poses[:, 0], poses[:, 1]))
    lm = landmarks.reshape(-1, 2)
    if len(lm):
        lm = np.column_stack(apply_fit(ev["_fit"], lm[:, 0], lm[:, 1]))
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


def dead_reckoning(data: VictoriaParkData, geometry: AckermannGeometry) -> np.ndarray:
    """Laser poses (T, 3) of the Ackermann model's Euler steps alone (vectorised: the
    heading depends on the controls only)."""
    g = geometry
    dt = np.diff(data.dr_time_s, append=data.dr_time_s[-1])
    t = np.tan(data.steering_rad)
    vc = data.speed_mps / (1.0 - t * g.encoder_left_m / g.wheelbase_m)
    k = t / g.wheelbase_m
    th = np.concatenate([[0.0], np.cumsum(dt * vc * k)[:-1]])
    c, s = np.cos(th), np.sin(th)
    a, b = g.laser_ahead_m, g.laser_left_m
    dx = vc * (c - k * (a * s + b * c))
    dy = vc * (s + k * (a * c - b * s))
    x = np.concatenate([[0.0], np.cumsum(dt * dx)[:-1]])
    y = np.concatenate([[0.0], np.cumsum(dt * dy)[:-1]])
    return np.stack([x, y, th], 1)


def windowed_dr_error(
    data: VictoriaParkData,
    geometry: AckermannGeometry,
    keep: np.ndarray,
    window_s: float = 60.0,
    min_fixes: int = 150,
) -> dict[str, float]:
    """Dead reckoning against GPS in 60 s windows (30 s apart), each rigidly aligned on
    its own: the local odometry error, sensitive to a, b, H, L without any SLAM."""
    poses = dead_reckoning(data, geometry)
    t = data.gps_time_s
    rms = []
    for t0 in np.arange(data.dr_time_s[0], data.dr_time_s[-1] - window_s, window_s / 2):
        sel = keep & (t >= t0) & (t < t0 + window_s)
        if sel.sum() < min_fixes:
            continue
        k = np.searchsorted(data.dr_time_s, t[sel], side="right") - 1
        est = poses[np.maximum(k, 0), :2]
        gps = np.stack([data.gps_x_m[sel], data.gps_y_m[sel]], 1)
        if np.ptp(gps, axis=0).max() < 20.0:  # the car hardly moved: nothing to judge
            continue
        fx, fy = apply_fit(rigid_fit(est, gps), est[:, 0], est[:, 1])
        rms.append(np.sqrt(np.mean((fx - gps[:, 0]) ** 2 + (fy - gps[:, 1]) ** 2)))
    rms = np.array(rms)
    return {"windows": len(rms), "median_m": float(np.median(rms)), "mean_m": float(rms.mean())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=_find_data())
    ap.add_argument("--geometry", choices=sorted(GEOMETRIES), default="drawing")
    ap.add_argument("--association", choices=["nn", "jcbb"], default="nn")
    ap.add_argument("--compare", action="store_true", help="also run every geometry variant")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "out")
    ap.add_argument(
        "--baseline",
        type=Path,
        help="another hilnav checkout (the old code): its bench/victoria_park.py runs "
        "between ours, both figures printed side by side (bench/baseline.py)",
    )
    ap.add_argument("--repeat", type=int, default=1, help="timed runs (the fastest kept)")
    args = ap.parse_args(argv)

    data = load_victoria_park(args.data)
    keep = gps_keep(data)
    print(f"GPS: {len(keep)} fixes, {int((~keep).sum())} excluded as outliers")
    results = {}
    if args.compare:
        for name, geom in GEOMETRIES.items():
            dr = windowed_dr_error(data, geom, keep)
            cfg = replace(BASE, geometry=geom, association=args.association)
            times, poses, slam = run_slam(data, cfg, max_landmarks=1000)
            ev = evaluate(data, times, poses, keep)
            done = times[-1] >= data.scan_time_s[-1] - 1.0
            results[name] = {
                "dr_window_median_m": round(dr["median_m"], 2),
                "dr_window_mean_m": round(dr["mean_m"], 2),
                "dr_windows": dr["windows"],
                "slam_ate_rmse_m": round(ev["ate_rmse_m"], 2) if done else None,
                "slam_max_err_m": round(ev["max_err_m"], 2) if done else None,
                "landmarks": slam.ekf.n_landmarks,
                "slam_diverged_at_s": None if done else round(float(times[-1] - times[0]), 1),
            }
            print(f"geometry {name:12s} {geom}: {results[name]}", flush=True)

    cfg = replace(BASE, geometry=GEOMETRIES[args.geometry], association=args.association)
    seconds = float("inf")
    before: list[dict] = []
    for _ in range(max(args.repeat, 1)):
        t0 = time.perf_counter()
        times, poses, slam = run_slam(data, cfg)
        seconds = min(seconds, time.perf_counter() - t0)
        if args.baseline:
            before.append(
                run_baseline(
                    args.baseline,
                    "bench/victoria_park.py",
                    "--data",
                    str(args.data),
                    "--association",
                    args.association,
                    "--geometry",
                    args.geometry,
                    "--out",
                    str(args.out / "baseline"),
                )  # fmt: skip
            )
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
    if before:
        fastest = min(before, key=lambda b: b["seconds"])
        out["baseline"] = {k: fastest[k] for k in ("ate_rmse_m", "max_err_m", "median_err_m",
                                                   "landmarks", "seconds", "realtime_factor")}  # fmt: skip
        print(f"before: {out['baseline']}")
        print(f"after:  ATE {out['ate_rmse_m']} m, {out['seconds']} s, {out['realtime_factor']}x")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
