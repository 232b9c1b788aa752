"""Benchmark: the MRCLAM EKF (localization/mrclam_ekf.py) on a real MRCLAM run directory.

Every robot of the run over the whole run, cooperative (robot-to-robot range-bearing
fused by covariance intersection) and single (landmarks only), default configuration
(derived in docs/algorithms.md, not fitted to any run). Scored at the track's instants
where the motion-capture truth exists (``truth_at``'s gap mask); the commands are
shifted by the configured lag, so the track is on the truth's clock:

- position RMSE (m) per robot and pooled over all scored instants of all robots;
- 3-sigma containment: fraction of instants with x, y and theta all within 3 sigma;
- the measurement counts (accepted, gated, CI with no gain) summed over the robots;
- realtime_factor: run duration / wall time of the cooperative pass (all robots).

``--ablations`` adds single-change variants of the cooperative filter (no command lag,
no AR(1) inflation, no bias states (white noise calibrated at 10 s), white noise only
calibrated at the README's 0.2 s window, AR(1) time 5 s, CI by trace, observer-only
peer update), so the effect of each default can be seen side by side.

The LAST line is a JSON object with those figures.

    python3 bench/mrclam_ekf.py [DIR] [--robots 1 2 3] [--ablations]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from localization.mrclam import load_mrclam
from localization.mrclam_ekf import MrclamEkfConfig, run_ekf, score_track

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "shared/data/mrclam/MRCLAM_Dataset6"
COUNTS = (
    "landmark_accepted",
    "landmark_gated",
    "robot_accepted",
    "robot_no_gain",
    "robot_gated",
    "seen_accepted",
)


def evaluate(run, robots, cooperative: bool, cfg: MrclamEkfConfig) -> dict:
    t0 = time.perf_counter()
    tracks = run_ekf(run, robots, cooperative, cfg)
    wall = time.perf_counter() - t0
    per, counts = {}, Counter()
    sq = inside = n = 0.0
    for k, tr in tracks.items():
        sc = score_track(tr, run.robots[k])
        per[k] = sc
        counts.update(tr.counts)
        if sc["scored"]:
            sq += sc["rmse_m"] ** 2 * sc["scored"]
            inside += sc["containment"] * sc["scored"]
            n += sc["scored"]
    return {
        "per_robot": per,
        "rmse_m": float(np.sqrt(sq / n)) if n else float("nan"),
        "containment": inside / n if n else float("nan"),
        "containment_min": min(s["containment"] for s in per.values()),
        "counts": {c: counts[c] for c in COUNTS},
        "wall_s": wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("directory", nargs="?", default=str(DEFAULT_DIR))
    ap.add_argument("--robots", type=int, nargs="*", default=None)
    ap.add_argument("--ablations", action="store_true")
    a = ap.parse_args()
    run = load_mrclam(a.directory)
    robots = sorted(run.robots) if a.robots is None else a.robots
    duration = run.end_s - run.start_s
    cfg = MrclamEkfConfig()
    coop = evaluate(run, robots, True, cfg)
    single = evaluate(run, robots, False, cfg)
    print(f"{Path(a.directory).name}: {len(robots)} robots, {duration:.0f} s")
    print(f"{'robot':>5} {'mode':>6} {'RMSE m':>7} {'head rad':>8} {'3sig':>6} {'3sig xy':>7}")
    for k in robots:
        for name, res in (("coop", coop), ("single", single)):
            s = res["per_robot"][k]
            print(
                f"{k:>5} {name:>6} {s['rmse_m']:7.3f} {s['heading_rmse_rad']:8.3f} "
                f"{s['containment']:6.3f} {s['containment_xy']:7.3f}"
            )
    for name, res in (("coop", coop), ("single", single)):
        print(
            f"{'all':>5} {name:>6} {res['rmse_m']:7.3f} {'':8} {res['containment']:6.3f}"
            f"   counts {res['counts']}  wall {res['wall_s']:.1f} s"
        )
    ablations = {}
    if a.ablations:
        variants = {
            "no_command_lag": replace(cfg, command_lag_s=0.0),
            "no_ar1_inflation": replace(cfg, error_correlation_s=0.0),
            "no_bias_states": replace(
                cfg,
                speed_scale_sigma=0.0,
                turn_bias_sigma_radps=0.0,
                v_sigma_rel=0.04,
                w_sigma_radps=0.0114,
            ),
            "white_noise_at_0.2s_readme": replace(
                cfg,
                speed_scale_sigma=0.0,
                turn_bias_sigma_radps=0.0,
                noise_window_s=0.2,
                v_sigma_mps=0.010,
                v_sigma_rel=0.09,
                w_sigma_radps=0.12 / 1.96,
            ),
            "ar1_tau_5s": replace(cfg, error_correlation_s=5.0),
            "ci_trace": replace(cfg, ci_criterion="trace"),
            "peer_update_observer": replace(cfg, peer_update="observer"),
        }
        print(f"{'variant (cooperative)':>26} {'RMSE m':>7} {'3sig':>6} {'3sig min':>8}")
        for name, v in variants.items():
            res = evaluate(run, robots, True, v)
            ablations[name] = {
                "ekf_rmse_m": round(res["rmse_m"], 4),
                "ekf_containment": round(res["containment"], 4),
                "ekf_containment_min": round(res["containment_min"], 4),
            }
            print(
                f"{name:>26} {res['rmse_m']:7.3f} {res['containment']:6.3f} "
                f"{res['containment_min']:8.3f}"
            )
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    out = {
        "directory": Path(a.directory).name,
        "robots": robots,
        "duration_s": round(duration, 1),
        "ekf_rmse_m": round(coop["rmse_m"], 4),
        "ekf_rmse_m_per_robot": {k: round(s["rmse_m"], 4) for k, s in coop["per_robot"].items()},
        "ekf_containment": round(coop["containment"], 4),
        "ekf_containment_per_robot": {
            k: round(s["containment"], 4) for k, s in coop["per_robot"].items()
        },
        "ekf_containment_min": round(coop["containment_min"], 4),
        "ekf_single_rmse_m": round(single["rmse_m"], 4),
        "ekf_single_containment": round(single["containment"], 4),
        "ekf_single_containment_min": round(single["containment_min"], 4),
        "counts": coop["counts"],
        "realtime_factor": round(duration / coop["wall_s"], 1),
        "ablations": ablations,
        "loadavg": load,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
