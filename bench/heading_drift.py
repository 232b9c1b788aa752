"""Benchmark: ir-grid-mapping.txt Table 2 — heading error per metre, encoder vs encoder+gyro.

20 simulated Pioneer 3-DX runs of 5-60 m on a flat floor (bench/fusion_sim.py: the fakes'
own wheel-slip and CruzCore error models, not tuned for the filter). As in the paper,
the heading error is measured every 5 m of driving (and at the end of the run); per run
the absolute errors are summed and divided by the summed distances of the checkpoints
(deg/m); Table 2's figure is the mean over the runs (the max is printed too).

- encoder: the odometry's own heading (fusion.heading.HeadingFilter fed odometry only,
  which is prediction only, eq. 1);
- fused: HeadingFilter fed odometry and gyro (eq. 1-4, the paper's alpha, beta, gamma;
  gyro bias learnt during the 3 s standstill at the start);
- fused_paper_literal: the same with eq. (1)-(3) read literally (model="paper").

Also printed: the fraction of checkpoints where the fused error is inside the filter's
3-sigma, and the mean NEES of the heading (1 for a consistent filter).
The LAST line is a JSON object with encoder_deg_per_m, fused_deg_per_m, ratio (paper:
0.53, 0.19, 0.36), per-run figures and timings.

    python bench/heading_drift.py [--runs 20] [--seed 1]
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
from fusion.heading import HeadingFilter, HeadingParams
from msgs import GyroSample, RobotOdometry, wrap_angle

CHECK_EVERY_M = 5.0


def checkpoints(run: SimRun) -> list[int]:
    """Indices of the odometry messages at every 5 m of true distance and at the end."""
    out, nxt = [], CHECK_EVERY_M
    for i, d in enumerate(run.distance_m):
        if d >= nxt:
            out.append(i)
            nxt += CHECK_EVERY_M
    last = len(run.distance_m) - 1
    if not out or out[-1] != last:
        out.append(last)
    return out


def track(run: SimRun, params: HeadingParams | None, use_gyro: bool) -> list[tuple[float, float]]:
    """(theta, variance) of the filter at every odometry message of the run."""
    f = HeadingFilter(params)
    out = []
    for m in run.messages:
        if isinstance(m, RobotOdometry):
            est = f.feed_odometry(m)
            if est is None:
                raise RuntimeError("odometry step skipped in a clean simulated run")
            out.append((est.theta_rad, est.variance_rad2))
        elif use_gyro and isinstance(m, GyroSample):
            f.feed_gyro(m)
    return out


def per_metre(run: SimRun, est: list[tuple[float, float]]) -> dict:
    idx = checkpoints(run)
    errs = np.array([wrap_angle(est[i][0] - run.truth[i].theta) for i in idx])
    sig = np.sqrt([est[i][1] for i in idx])
    dist = np.array([run.distance_m[i] for i in idx])
    return {
        "deg_per_m": float(np.degrees(np.abs(errs).sum()) / dist.sum()),
        "final_error_deg": float(np.degrees(errs[-1])),
        "inside_3sigma": int(np.sum(np.abs(errs) <= 3.0 * sig)),
        "nees": float(np.mean(errs**2 / sig**2)),
        "checkpoints": len(idx),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    runs = [
        simulate(args.seed * 1000 + i, length, with_gps=False)
        for i, length in enumerate(run_lengths(args.runs))
    ]
    t_sim = time.perf_counter() - t0
    t1 = time.perf_counter()
    variants = {
        "encoder": (HeadingParams(), False),
        "fused": (HeadingParams(), True),
        "fused_paper_literal": (HeadingParams(model="paper"), True),
    }
    res: dict[str, list[dict]] = {k: [] for k in variants}
    n_msgs = 0
    for run in runs:
        for name, (params, gyro) in variants.items():
            res[name].append(per_metre(run, track(run, params, gyro)))
        n_msgs += len(run.messages)
    t_filt = time.perf_counter() - t1

    def mean(name: str, key: str) -> float:
        return float(np.mean([r[key] for r in res[name]]))

    print(f"{'run':>3} {'len m':>6} {'gyro bias':>9} {'scale':>7} "
          f"{'enc deg/m':>9} {'fused deg/m':>11} {'enc end':>8} {'fused end':>9}")  # fmt: skip
    for i, run in enumerate(runs):
        e, f = res["encoder"][i], res["fused"][i]
        print(f"{i:3d} {run.distance_m[-1]:6.1f} {run.gyro_bias_degps:9.3f} "
              f"{run.gyro_scale:7.4f} {e['deg_per_m']:9.3f} {f['deg_per_m']:11.3f} "
              f"{e['final_error_deg']:8.2f} {f['final_error_deg']:9.2f}")  # fmt: skip
    enc, fus = mean("encoder", "deg_per_m"), mean("fused", "deg_per_m")
    n_chk = sum(r["checkpoints"] for r in res["fused"])
    result = {
        "bench": "heading_drift",
        "runs": len(runs),
        "encoder_deg_per_m": round(enc, 3),
        "fused_deg_per_m": round(fus, 3),
        "ratio": round(fus / enc, 3),
        "paper": {"encoder_deg_per_m": 0.53, "fused_deg_per_m": 0.19, "ratio": 0.36},
        "encoder_deg_per_m_max": round(max(r["deg_per_m"] for r in res["encoder"]), 3),
        "fused_deg_per_m_max": round(max(r["deg_per_m"] for r in res["fused"]), 3),
        "fused_paper_literal_deg_per_m": round(mean("fused_paper_literal", "deg_per_m"), 3),
        "fused_inside_3sigma": round(sum(r["inside_3sigma"] for r in res["fused"]) / n_chk, 3),
        "fused_paper_literal_inside_3sigma": round(
            sum(r["inside_3sigma"] for r in res["fused_paper_literal"]) / n_chk, 3
        ),
        "fused_heading_nees": round(mean("fused", "nees"), 2),
        "fused_paper_literal_heading_nees": round(mean("fused_paper_literal", "nees"), 2),
        "distance_total_m": round(sum(r.distance_m[-1] for r in runs), 1),
        "seconds_simulation": round(t_sim, 2),
        "seconds_filters": round(t_filt, 2),
        "messages_per_s": round(len(variants) * n_msgs / t_filt),
        "seed": args.seed,
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
