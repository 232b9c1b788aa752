"""Benchmark: the pose EKF (ekf-vs-cp.txt §2.2) with encoder, encoder+gyro, encoder+gyro+GPS.

The same 20 simulated Pioneer runs of 5-60 m as bench/heading_drift.py (fakes' own wheel
slip, CruzCore and GPS error models; bench/fusion_sim.py), GPS at 1 Hz in local metres.
For each sensor set the EKF (fusion.pose_ekf, default parameters) is fed the messages
in arrival order; at every odometry message its estimate is compared with the truth:

- position RMSE (m) over all odometry messages of all runs, and the mean final error;
- 3-sigma containment: fraction of messages where the truth is inside the EKF's 3-sigma
  box on x and y (PoseBox from ``bounds(3)``, the comparison ekf-vs-cp makes with CP's
  boxes), and on theta; a consistent Gaussian filter gives 0.995 per axis;
- mean NEES of (x, y, theta) (3 for a consistent filter);
- the gating/timeout counters summed over the runs;
- messages per second: messages the filter consumed per second of wall time.

The short runs last 15-150 s, less than the GPS bias's correlation time (120 s): the EKF,
which takes fixes as white noise, is pulled towards the bias there. The same figures on
``--long-runs`` runs of ``--long-length`` m (default 2 x 300 m, about 13 min each) show
GPS bounding the drift. ``encoder_gyro_gps`` is the default EKF, whose state carries the
GPS bias (east, north) as a first-order Gauss-Markov process with consumer-receiver
defaults (sigma 2 m, tau 300 s; fusion/pose_ekf.py), not the fake's figures (1.5 m,
120 s); ``encoder_gyro_gps_white`` is the 3-state filter taking fixes as white noise, and
``encoder_gyro_gps_tau120`` that filter with the error's correlation time (120 s) taken
into account by inflating R instead. Raw filter speed is
timed too: predictions (encoder only, and with a gyro step fused) and GPS updates per
second.

The LAST line is a JSON object with those figures per sensor set.

    python bench/pose_ekf.py [--runs 20] [--seed 1] [--long-runs 2] [--long-length 300]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.fusion_sim import SimRun, run_lengths, simulate
from fusion.pose_ekf import PoseEkf, PoseEkfParams
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry, wrap_angle

ODO, GYRO, GPS = RobotOdometry, GyroSample, GpsFix
# name -> (messages fed, parameters); defaults (GPS bias states on) but the last two rows:
# the 3-state filter taking fixes as white noise, and the same with R inflated by tau.
WHITE = PoseEkfParams(gps_bias_states=False)
SETS: dict[str, tuple[tuple[type, ...], PoseEkfParams]] = {
    "encoder": ((ODO,), PoseEkfParams()),
    "encoder_gyro": ((ODO, GYRO), PoseEkfParams()),
    "encoder_gyro_gps": ((ODO, GYRO, GPS), PoseEkfParams()),
    "encoder_gyro_gps_white": ((ODO, GYRO, GPS), WHITE),
    "encoder_gyro_gps_tau120": (
        (ODO, GYRO, GPS),
        PoseEkfParams(gps_bias_states=False, gps_error_correlation_s=120.0),
    ),
}


def run_filter(run: SimRun, kinds: tuple[type, ...], params: PoseEkfParams) -> dict:
    ekf = PoseEkf(params, initial=Pose2D(0.0, 0.0, 0.0))
    errs, boxes_in, th_in, nees = [], 0, 0, []
    i = 0
    n_fed = 0
    t0 = time.perf_counter()
    states = []
    for m in run.messages:
        if not isinstance(m, kinds):
            continue
        n_fed += 1
        ekf.feed(m)
        if isinstance(m, RobotOdometry):
            states.append((ekf.x[:3].copy(), ekf.P[:3, :3].copy()))
    seconds = time.perf_counter() - t0
    for i, (x, p) in enumerate(states):
        t = run.truth[i]
        e = np.array([x[0] - t.x, x[1] - t.y, wrap_angle(x[2] - t.theta)])
        s = np.sqrt(np.diag(p))
        errs.append(e)
        boxes_in += int(abs(e[0]) <= 3 * s[0] and abs(e[1]) <= 3 * s[1])
        th_in += int(abs(e[2]) <= 3 * s[2])
        nees.append(float(e @ np.linalg.solve(p, e)))
    e = np.array(errs)
    return {
        "sq_pos": float(np.sum(e[:, 0] ** 2 + e[:, 1] ** 2)),
        "n": len(e),
        "final_pos_err": float(np.hypot(e[-1, 0], e[-1, 1])),
        "box_in": boxes_in,
        "theta_in": th_in,
        "nees_sum": float(np.sum(nees)),
        "fed": n_fed,
        "seconds": seconds,
        "counters": ekf.counters(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--long-runs", type=int, default=2)
    ap.add_argument("--long-length", type=float, default=300.0)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    lengths = run_lengths(args.runs)
    runs = [simulate(args.seed * 1000 + i, length) for i, length in enumerate(lengths)]
    long_runs = [
        simulate(args.seed * 1000 + 500 + i, args.long_length) for i in range(args.long_runs)
    ]
    t_sim = time.perf_counter() - t0
    out = evaluate(runs, f"{len(runs)} runs of 5-60 m")
    out_long = evaluate(long_runs, f"{len(long_runs)} runs of {args.long_length:g} m")
    rates = speed()
    print(" ".join(f"{k}={v}" for k, v in rates.items()))
    result = {
        "bench": "pose_ekf",
        "runs": len(runs),
        **out,
        "distance_total_m": round(sum(r.distance_m[-1] for r in runs), 1),
        "long_runs": {"runs": len(long_runs), "length_m": args.long_length, **out_long},
        **rates,
        "seconds_simulation": round(t_sim, 2),
        "seconds": round(time.perf_counter() - t0, 2),
        "seed": args.seed,
    }
    print(json.dumps(result))
    return 0


def speed(n: int = 5000) -> dict[str, int]:
    """Raw rates of the array-level API on one filter."""
    rng = np.random.default_rng(0)
    wheels = rng.uniform(0.0, 0.05, size=(n, 2))
    gyro = rng.normal(0.0, 0.01, size=n)
    ekf = PoseEkf(PoseEkfParams(gate_probability=None), initial=Pose2D())
    t = time.perf_counter()
    for dl, dr in wheels:
        ekf.predict(float(dl), float(dr))
    t_pred = time.perf_counter() - t
    t = time.perf_counter()
    for (dl, dr), g in zip(wheels, gyro, strict=True):
        ekf.predict(float(dl), float(dr), float(g), 1e-6)
    t_gyro = time.perf_counter() - t
    r = np.eye(2)
    t = time.perf_counter()
    for _ in range(n):
        ekf.update_position(ekf.x[:2], r)
    t_gps = time.perf_counter() - t
    return {
        "predict_per_s": round(n / t_pred),
        "predict_with_gyro_per_s": round(n / t_gyro),
        "gps_update_per_s": round(n / t_gps),
    }


def evaluate(runs: list[SimRun], title: str) -> dict[str, dict]:
    out: dict[str, dict] = {}
    print(title)
    print(f"{'sensors':>23} {'RMSE m':>7} {'final m':>7} {'in 3s xy':>8} {'in 3s th':>8} "
          f"{'NEES':>6} {'msgs/s':>8}")  # fmt: skip
    for name, (kinds, params) in SETS.items():
        rs = [run_filter(r, kinds, params) for r in runs]
        n = sum(r["n"] for r in rs)
        counters: dict[str, float] = {}
        for r in rs:
            for k, v in r["counters"].items():
                if isinstance(v, bool):
                    continue
                if isinstance(v, int):
                    counters[k] = counters.get(k, 0) + v
        fig = {
            "position_rmse_m": round(float(np.sqrt(sum(r["sq_pos"] for r in rs) / n)), 3),
            "final_position_error_m_mean": round(
                float(np.mean([r["final_pos_err"] for r in rs])), 3
            ),
            "inside_3sigma_xy": round(sum(r["box_in"] for r in rs) / n, 3),
            "inside_3sigma_theta": round(sum(r["theta_in"] for r in rs) / n, 3),
            "nees_mean": round(sum(r["nees_sum"] for r in rs) / n, 2),
            "messages_per_s": round(sum(r["fed"] for r in rs) / sum(r["seconds"] for r in rs)),
            "counters": {k: v for k, v in counters.items() if v and k not in ("resets",)},
        }
        out[name] = fig
        print(f"{name:>23} {fig['position_rmse_m']:7.3f} {fig['final_position_error_m_mean']:7.3f} "
              f"{fig['inside_3sigma_xy']:8.3f} {fig['inside_3sigma_theta']:8.3f} "
              f"{fig['nees_mean']:6.2f} {fig['messages_per_s']:8d}")  # fmt: skip
    return out


if __name__ == "__main__":
    raise SystemExit(main())
