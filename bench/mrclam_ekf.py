"""Benchmark: the MRCLAM EKF (localization/mrclam_ekf.py) on a real MRCLAM run directory.

Every robot of the run over the whole run, default configuration (derived in
docs/algorithms.md from error statistics, not fitted to any score), side by side in one
run:

- ``joint``: the default, one filter over all the robots with their cross-covariances
  (the centralized equivalent);
- ``split_ci``: one filter per robot fed the others' published estimates, split
  covariance intersection (what ``hilnav replay`` runs, robot by robot);
- ``ci``: the same with covariance intersection (everything of unknown correlation);
- ``single``: landmarks only.

Scored at the track's grid instants (every 0.05 s) where the motion-capture truth
exists (``truth_at``'s gap mask); the commands are shifted by the configured lag, so the
track is on the truth's clock:

- position RMSE (m) per robot and pooled over all scored instants of all robots;
- 3-sigma containment: fraction of instants with x, y and theta all within 3 sigma;
- the measurement counts (accepted, gated, no gain) summed over the robots;
- realtime_factor: run duration / wall time of the joint pass (all robots, one core).

``--ablations`` adds single-change variants of the joint filter (each default undone
alone; one of them on the single-robot filter, where it matters most), so the effect of
each can be seen side by side.

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
    "seen_no_gain",
    "seen_gated",
)
MODES = {"joint": "joint", "split_ci": "split_ci", "ci": "ci", "single": "none"}


def ablations(cfg: MrclamEkfConfig) -> dict[str, MrclamEkfConfig]:
    """Each default undone alone (docs/algorithms.md says why each is what it is)."""
    no_camera_states = {
        "camera_scale_sigma": 0.0,
        "camera_offset_sigma_m": 0.0,
        "camera_bearing_sigma_rad": 0.0,
        "camera_slope_sigma": 0.0,
        "camera_distortion_sigma": 0.0,
        "camera_common_sigma": (0.0, 0.0),
    }
    return {
        "range_model_no_camera_states": replace(
            cfg,
            camera_model="range",
            range_sigma_rel=0.095 / 1.96,
            range_sigma_quad=0.0,
            robot_target_offset_m=0.0,
            **no_camera_states,
        ),
        "no_camera_states": replace(cfg, **no_camera_states),
        "range_factor_at_predicted_bearing": replace(cfg, range_factor_bearing="predicted"),
        "single_range_factor_at_predicted_bearing": replace(
            cfg, range_factor_bearing="predicted", cooperation="none"
        ),
        "no_ar1_inflation": replace(cfg, error_correlation_s=(0.0, 0.0)),
        "ar1_per_target": replace(cfg, correlation_scope="subject"),
        "one_ar1_on_all_error_8s": replace(
            cfg,
            error_white_fraction=(0.0, 0.0),
            error_target_fraction=(1.0, 1.0),
            error_correlation_s=(8.0, 8.0),
            camera_common_sigma=(0.0, 0.0),
        ),
        "heading_noise_in_time": replace(
            cfg, w_noise_time=8.9e-4, w_noise_turn=0.0, turn_scale_sigma=0.0
        ),
        "no_command_lag": replace(cfg, command_lag_s=0.0),
        "no_robot_target_offset": replace(cfg, robot_target_offset_m=0.0),
        "split_ci_observer_only": replace(cfg, cooperation="split_ci", peer_update="observer"),
    }


def evaluate(run, robots, cfg: MrclamEkfConfig) -> dict:
    t0 = time.perf_counter()
    tracks = run_ekf(run, robots, config=cfg)
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


def _short(res: dict) -> dict:
    return {
        "rmse_m": round(res["rmse_m"], 4),
        "containment": round(res["containment"], 4),
        "containment_min": round(res["containment_min"], 4),
        "rmse_m_per_robot": {k: round(s["rmse_m"], 4) for k, s in res["per_robot"].items()},
        "containment_per_robot": {
            k: round(s["containment"], 4) for k, s in res["per_robot"].items()
        },
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
    res = {name: evaluate(run, robots, replace(cfg, cooperation=m)) for name, m in MODES.items()}
    print(f"{Path(a.directory).name}: {len(robots)} robots, {duration:.0f} s")
    print(f"{'robot':>5} " + " ".join(f"{m + ' RMSE/3sig':>20}" for m in MODES))
    for k in robots:
        cells = [f"{r['per_robot'][k]['rmse_m']:7.3f} / {r['per_robot'][k]['containment']:5.3f}"
                 for r in res.values()]  # fmt: skip
        print(f"{k:>5} " + " ".join(f"{c:>20}" for c in cells))
    cells = [f"{r['rmse_m']:7.3f} / {r['containment']:5.3f}" for r in res.values()]
    print(f"{'all':>5} " + " ".join(f"{c:>20}" for c in cells))
    for name, r in res.items():
        print(f"  {name}: counts {r['counts']}  wall {r['wall_s']:.1f} s")
    abl = {}
    if a.ablations:
        print(f"{'variant (joint, one change)':>36} {'RMSE m':>7} {'3sig':>6} {'3sig min':>8}")
        for name, v in ablations(cfg).items():
            r = evaluate(run, robots, v)
            abl[name] = _short(r)
            print(
                f"{name:>36} {r['rmse_m']:7.3f} {r['containment']:6.3f} {r['containment_min']:8.3f}"
            )
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    joint = res["joint"]
    out = {
        "directory": Path(a.directory).name,
        "robots": robots,
        "duration_s": round(duration, 1),
        "cooperation": cfg.cooperation,
        "ekf_rmse_m": round(joint["rmse_m"], 4),
        "ekf_rmse_m_per_robot": _short(joint)["rmse_m_per_robot"],
        "ekf_containment": round(joint["containment"], 4),
        "ekf_containment_per_robot": _short(joint)["containment_per_robot"],
        "ekf_containment_min": round(joint["containment_min"], 4),
        "ekf_single_rmse_m": round(res["single"]["rmse_m"], 4),
        "ekf_single_containment": round(res["single"]["containment"], 4),
        "ekf_single_containment_min": round(res["single"]["containment_min"], 4),
        "modes": {name: _short(r) for name, r in res.items()},
        "counts": {name: r["counts"] for name, r in res.items()},
        "realtime_factor": round(duration / joint["wall_s"], 1),
        "ablations": abl,
        "loadavg": load,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
