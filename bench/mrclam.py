"""Benchmark: guaranteed (CP) and EKF localization of every robot of a real MRCLAM run
(issue 14 item 6), alone and cooperatively, in one process.

    python3 bench/mrclam.py [DIR] [--seconds S] [--robots 1,2,3] [--tick 0.1] [--no-ekf]
                            [--decompose] [--set KEY=VALUE ...]

DIR is any MRCLAM run directory (default ../shared/data/mrclam/MRCLAM_Dataset6; every
run of the data set has the same files). Localizers, all over the merged time-ordered
stream of the five robots (``localization.mrclam_cp``, ``localization.mrclam_ekf``):

- single CP: each robot alone (velocity odometry + landmark range-bearing);
- cooperative CP: also range-bearing to and from the other robots, whose published
  boxes are aged by their stamps;
- EKF (cooperative, covariance intersection), and its integrity monitor against the
  cooperative CP boxes.

Scoring: CP boxes are reported every ``--tick`` s and scored against the motion-capture
truth at the same instant, where it exists (``RobotRun.truth_at``: no truth in gaps
over 0.25 s). The same instant, not shifted: the camera's bearings line up with the
truth best at zero delay; the 0.16-0.20 s lag is that of the commanded velocities, which
the odometry model applies (``command_lag_s``). Containment: x, y inside and the heading
inside modulo 2 pi. Areas and heading widths are medians over all robots' scored ticks
(unbounded boxes count as infinite, heading widths are capped at 2 pi); also over the
"fresh" ticks alone, whose box comes from a state solved at most 1 s before (the robot
saw landmarks or peers), apart from the stretches it drives blind.

``--decompose`` also prints where the cooperative boxes' size comes from: median area
and heading width by the time since the robot last saw a landmark, and right after a
frame (< 0.5 s) by the number of landmarks in it.

Prints a table per robot, then ONE JSON object as the last line: cp_containment_min,
cp_area_median_m2 (cooperative), cp_single_area_median_m2, cp_heading_width_median_rad,
the single CP's, ekf_rmse_m, ekf_containment (3 sigma), alarms, false_alarms,
realtime_factor (cooperative CP, five robots, whole run, wall clock), its CPU-time
version (less distorted on a busy machine), and the same for the whole bench.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from localization.cp_config import RangeBearingCPConfig
from localization.ekf import BoxTrack, integrity_counts
from localization.mrclam import MrclamRun, load_mrclam
from localization.mrclam_cp import CpTrack, containment, run_cp
from localization.mrclam_ekf import run_ekf
from localization.mrclam_track import score_track

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "shared/data/mrclam/MRCLAM_Dataset6"
TWO_PI = 2.0 * np.pi
#: Boxes predicted from a state solved at most this long before ("fresh": landmarks or
#: peers in view) are also scored apart from those of the stretches without any.
FRESH_S = 1.0


#: Bins of the decomposition (``--decompose``): seconds since the last landmark sighting.
SINCE_BINS = (0.0, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, np.inf)


def since_landmark(run: MrclamRun, r: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per instant: seconds since robot ``r`` last saw a landmark (inf before the first),
    and how many landmarks that frame held."""
    m = run.robots[r].measurements
    lm = m[np.isin(m[:, 1].astype(int), list(run.landmarks)), 0]
    frames, count = np.unique(lm, return_counts=True)
    i = np.searchsorted(frames, t, side="right") - 1
    since = np.where(i >= 0, t - frames[np.maximum(i, 0)], np.inf)
    return since, np.where(i >= 0, count[np.maximum(i, 0)], 0)


def decompose(run: MrclamRun, tracks: dict[int, CpTrack]) -> list[tuple[str, float, float, float]]:
    """Where the boxes' size comes from: (bin, fraction of the scored ticks, median area,
    median heading width) by the time since the last landmark sighting, then by the
    number of landmarks of that frame (ticks less than 0.5 s after it)."""
    rows, cols = [], {"area": [], "hw": [], "since": [], "n": []}
    for r, tr in tracks.items():
        _, has = run.robots[r].truth_at(tr.t)
        since, n = since_landmark(run, r, tr.t)
        w = tr.box[:, 1] - tr.box[:, 0]
        with np.errstate(invalid="ignore"):
            cols["area"].append(
                np.where(np.isfinite(w[:, 0] * w[:, 1]), w[:, 0] * w[:, 1], np.inf)[has]
            )
        cols["hw"].append(
            np.minimum(np.nan_to_num(w[:, 2], nan=TWO_PI, posinf=TWO_PI), TWO_PI)[has]
        )
        cols["since"].append(since[has])
        cols["n"].append(n[has])
    a, h, since, n = (np.concatenate(cols[k]) for k in ("area", "hw", "since", "n"))
    bins = [
        (f"{lo:g}-{hi:g} s", (since >= lo) & (since < hi))
        for lo, hi in zip(SINCE_BINS[:-1], SINCE_BINS[1:], strict=True)
    ]
    bins += [(f"{k} landmark(s), < 0.5 s", (n == k) & (since < 0.5)) for k in range(1, 7)]
    for name, sel in bins:
        if sel.any():
            rows.append(
                (name, float(sel.mean()), float(np.median(a[sel])), float(np.median(h[sel])))
            )
    return rows


def score_cp(run: MrclamRun, tracks: dict[int, CpTrack]) -> dict:
    """Per robot and pooled: containment, areas, heading widths at scored ticks."""
    per, areas, widths, fresh = {}, [], [], []
    for r, tr in tracks.items():
        pose, has = run.robots[r].truth_at(tr.t)
        inside = containment(tr, pose)[has]
        w = tr.box[:, 1] - tr.box[:, 0]
        with np.errstate(invalid="ignore"):
            area = np.where(np.isfinite(w[:, 0] * w[:, 1]), w[:, 0] * w[:, 1], np.inf)[has]
        hw = np.minimum(np.nan_to_num(w[:, 2], nan=TWO_PI, posinf=TWO_PI), TWO_PI)[has]
        areas.append(area)
        widths.append(hw)
        fresh.append(tr.age[has] <= FRESH_S)
        misses = tr.t[has][~inside]
        per[r] = {
            "scored": int(has.sum()),
            "containment": float(inside.mean()) if inside.size else float("nan"),
            "misses": int((~inside).sum()),
            "first_miss_s": float(misses[0] - run.start_s) if misses.size else None,
            "area_median_m2": float(np.median(area)) if area.size else float("nan"),
            "heading_width_median_rad": float(np.median(hw)) if hw.size else float("nan"),
            "observations": tr.observations,
            "solves": tr.solves,
            "outliers_named": len(tr.outliers),
            "lost": sum(1 for _, e in tr.events if e == "lost"),
            "reinit": sum(1 for _, e in tr.events if e == "reinit"),
        }
    a, h, f = np.concatenate(areas), np.concatenate(widths), np.concatenate(fresh)
    return {
        "area_median_fresh_m2": float(np.median(a[f])) if f.any() else float("nan"),
        "heading_width_median_fresh_rad": float(np.median(h[f])) if f.any() else float("nan"),
        "fresh_fraction": float(f.mean()) if f.size else float("nan"),
        "robots": per,
        "containment_min": min(p["containment"] for p in per.values()),
        "area_median_m2": float(np.median(a)) if a.size else float("nan"),
        "heading_width_median_rad": float(np.median(h)) if h.size else float("nan"),
    }


def _no_score(ids: list[int]) -> dict:
    """The single CP's score when it was not run (``--no-single``)."""
    nan = float("nan")
    per = {r: {"containment": nan, "area_median_m2": nan} for r in ids}
    return {"robots": per, "containment_min": nan, "area_median_m2": nan,
            "heading_width_median_rad": nan}  # fmt: skip


def _timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def run_ekf_part(run: MrclamRun, robots: list[int], coop: dict[int, CpTrack]) -> dict:
    """The EKF (``localization.mrclam_ekf``, cooperative) and its integrity monitor
    against the cooperative CP boxes."""
    tracks, wall, cpu = _timed(lambda: run_ekf(run, robots, cooperative=True))
    sq, inside, n, alarms, false_alarms = 0.0, 0, 0, 0, 0
    per = {}
    for r, tr in tracks.items():
        s = score_track(tr, run.robots[r])
        per[r] = s
        sq += s["rmse_m"] ** 2 * s["scored"]
        inside += s["containment"] * s["scored"]
        n += s["scored"]
        cp = coop[r]
        pose, has = run.robots[r].truth_at(cp.t)
        ic = integrity_counts(tr, BoxTrack(cp.t, cp.box[:, 0], cp.box[:, 1]), (pose, has))
        alarms += ic["alarms"]
        false_alarms += ic["false_alarms"]
        per[r].update(alarms=ic["alarms"], false_alarms=ic["false_alarms"])
    return {
        "ekf_robots": per,
        "ekf_rmse_m": float(np.sqrt(sq / max(n, 1))),
        "ekf_containment": float(inside / max(n, 1)),
        "alarms": int(alarms),
        "false_alarms": int(false_alarms),
        "ekf_wall_s": wall,
        "ekf_cpu_s": cpu,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", nargs="?", default=str(DEFAULT_DIR), help="an MRCLAM run directory")
    ap.add_argument("--seconds", type=float, default=None, help="cut the run after S seconds")
    ap.add_argument("--robots", default=None, help="comma-separated subjects (default: all)")
    ap.add_argument("--tick", type=float, default=0.1, help="box report period (s)")
    ap.add_argument("--outliers", type=int, default=None, help="q (default: the config's)")
    ap.add_argument("--solve-period", type=float, default=None, help="CP solve period (s)")
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a RangeBearingCPConfig field (repeatable; for ablations)",
    )
    ap.add_argument("--no-ekf", action="store_true", help="CP only")
    ap.add_argument("--no-single", action="store_true", help="cooperative CP only")
    ap.add_argument(
        "--decompose",
        action="store_true",
        help="also the cooperative boxes' size by time since the last landmark sighting and "
        "by landmarks in that frame",
    )
    args = ap.parse_args(argv)
    robots = [int(r) for r in args.robots.split(",")] if args.robots else None
    (run, load_s, _) = _timed(lambda: load_mrclam(args.dir, robots))
    ids = sorted(run.robots)
    end = run.end_s if args.seconds is None else min(run.end_s, run.start_s + args.seconds)
    seconds = end - run.start_s
    cfg = RangeBearingCPConfig()
    if args.outliers is not None:
        cfg = replace(cfg, outliers=args.outliers)
    if args.solve_period is not None:
        cfg = replace(cfg, solve_period_s=args.solve_period)
    for kv in args.set:
        key, _, value = kv.partition("=")
        cfg = replace(cfg, **{key.strip(): ast.literal_eval(value.strip())})
    single, s_wall, s_cpu = (
        _timed(lambda: run_cp(run, ids, False, cfg, tick_s=args.tick, end_s=end))
        if not args.no_single
        else (None, 0.0, 0.0)
    )
    coop, c_wall, c_cpu = _timed(lambda: run_cp(run, ids, True, cfg, tick_s=args.tick, end_s=end))
    c_score = score_cp(run, coop)
    s_score = score_cp(run, single) if single is not None else _no_score(ids)
    with np.errstate(invalid="ignore"):
        ekf = {} if args.no_ekf else run_ekf_part(_cut(run, end), ids, coop)
    print(f"MRCLAM {Path(args.dir).name}: robots {ids}, {seconds:.0f} s, tick {args.tick} s")
    print(f"{'robot':>5} {'single in':>9} {'area':>7} {'coop in':>8} {'area':>7} {'hdg':>6}"
          f" {'obs':>6} {'solves':>6} {'named':>5} {'lost':>4} {'ekf rmse':>8} {'ekf 3s':>6}")  # fmt: skip
    for r in ids:
        s, c = s_score["robots"][r], c_score["robots"][r]
        e = ekf.get("ekf_robots", {}).get(r, {})
        print(
            f"{r:>5} {s['containment']:>9.4f} {s['area_median_m2']:>7.2f} {c['containment']:>8.4f}"
            f" {c['area_median_m2']:>7.2f} {c['heading_width_median_rad']:>6.2f} {c['observations']:>6}"
            f" {c['solves']:>6} {c['outliers_named']:>5} {c['lost']:>4}"
            f" {e.get('rmse_m', float('nan')):>8.3f} {e.get('containment', float('nan')):>6.3f}"
        )
    if args.decompose:
        print(f"{'cooperative CP, ticks':>28} {'fraction':>8} {'area':>7} {'hdg':>6}")
        for name, frac, area, hw in decompose(run, coop):
            print(f"{name:>28} {frac:>8.3f} {area:>7.2f} {hw:>6.2f}")
    total_wall = load_s + s_wall + c_wall + ekf.get("ekf_wall_s", 0.0)
    total_cpu = s_cpu + c_cpu + ekf.get("ekf_cpu_s", 0.0)
    out = {
        "run": Path(args.dir).name,
        "robots": ids,
        "seconds": round(seconds, 3),
        "cp_containment_min": c_score["containment_min"],
        "cp_containment": {r: v["containment"] for r, v in c_score["robots"].items()},
        "cp_area_median_m2": c_score["area_median_m2"],
        "cp_single_area_median_m2": s_score["area_median_m2"],
        "cp_single_containment_min": s_score["containment_min"],
        "cp_heading_width_median_rad": c_score["heading_width_median_rad"],
        "cp_area_median_fresh_m2": c_score["area_median_fresh_m2"],
        "cp_heading_width_median_fresh_rad": c_score["heading_width_median_fresh_rad"],
        "cp_fresh_fraction": c_score["fresh_fraction"],
        "cp_single_heading_width_median_rad": s_score["heading_width_median_rad"],
        "cp_outliers_named": sum(v["outliers_named"] for v in c_score["robots"].values()),
        "cp_lost": sum(v["lost"] for v in c_score["robots"].values()),
        "outliers_q": cfg.outliers,
        "solve_period_s": cfg.solve_period_s,
        "config_overrides": args.set,
        "ekf_rmse_m": ekf.get("ekf_rmse_m"),
        "ekf_containment": ekf.get("ekf_containment"),
        "alarms": ekf.get("alarms"),
        "false_alarms": ekf.get("false_alarms"),
        "realtime_factor": seconds / c_wall,
        "realtime_factor_cpu": seconds / max(c_cpu, 1e-9),
        "realtime_factor_single": seconds / s_wall if s_wall > 0 else None,
        "realtime_factor_all": seconds / total_wall,
        "realtime_factor_all_cpu": seconds / max(total_cpu, 1e-9),
        "load": os.getloadavg()[0],
    }
    print(json.dumps({k: (None if v != v else v) for k, v in out.items()}))  # NaN: not run
    return 0


def _cut(run: MrclamRun, end: float) -> MrclamRun:
    """The run without anything after ``end`` (for the EKF, which runs whole runs)."""
    if end >= run.end_s:
        return run
    robots = {}
    for r, rr in run.robots.items():
        robots[r] = replace(
            rr,
            odometry=rr.odometry[rr.odometry[:, 0] <= end],
            measurements=rr.measurements[rr.measurements[:, 0] <= end],
            truth=rr.truth[rr.truth[:, 0] <= end + 1.0],
        )
    return replace(run, robots=robots)


if __name__ == "__main__":
    sys.exit(main())
