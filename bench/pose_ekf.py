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
- updates per second: messages the filter consumed per second of wall time.

The LAST line is a JSON object with those figures per sensor set.

    python bench/pose_ekf.py [--runs 20] [--seed 1]
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

from bench.fusion_sim import SimRun, run_lengths, simulate  # noqa: E402
from fusion.pose_ekf import PoseEkf, PoseEkfParams  # noqa: E402
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry, wrap_angle  # noqa: E402

SETS = {
    "encoder": (RobotOdometry,),
    "encoder_gyro": (RobotOdometry, GyroSample),
    "encoder_gyro_gps": (RobotOdometry, GyroSample, GpsFix),
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
            states.append((ekf.x.copy(), ekf.P.copy()))
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
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    runs = [
        simulate(args.seed * 1000 + i, length) for i, length in enumerate(run_lengths(args.runs))
    ]
    t_sim = time.perf_counter() - t0
    params = PoseEkfParams()
    out: dict[str, dict] = {}
    print(f"{'sensors':>17} {'RMSE m':>7} {'final m':>7} {'in 3s xy':>8} {'in 3s th':>8} "
          f"{'NEES':>6} {'upd/s':>8}")  # fmt: skip
    for name, kinds in SETS.items():
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
            "updates_per_s": round(sum(r["fed"] for r in rs) / sum(r["seconds"] for r in rs)),
            "counters": {k: v for k, v in counters.items() if v and k not in ("resets",)},
        }
        out[name] = fig
        print(f"{name:>17} {fig['position_rmse_m']:7.3f} {fig['final_position_error_m_mean']:7.3f} "
              f"{fig['inside_3sigma_xy']:8.3f} {fig['inside_3sigma_theta']:8.3f} "
              f"{fig['nees_mean']:6.2f} {fig['updates_per_s']:8d}")  # fmt: skip
    result = {
        "bench": "pose_ekf",
        "runs": len(runs),
        **out,
        "distance_total_m": round(sum(r.distance_m[-1] for r in runs), 1),
        "seconds_simulation": round(t_sim, 2),
        "seconds": round(time.perf_counter() - t0, 2),
        "seed": args.seed,
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
