"""Benchmark: how good must the poses be for the IR map to score well on a real log?

The IR map's occupied precision / recall (``bench/ir_real.py``, ``mapping.map_scores``:
within 2 cells of the laser map at the reference poses) falls as the poses it is drawn
at leave the reference. This bench measures how fast, with pose errors shaped as the
robot's own: each trajectory's error against the reference (position and heading, as
it grows along the run) is scaled by a fraction f and the IR map drawn at the reference
plus f times that error; f = 1 is the trajectory itself, f = 0 the reference. Error
shapes (real data, nothing simulated but the gyro):

- ``odometry``: the log's wheel odometry composed along the reference heading (its
  distance errors alone, the floor of any heading input: ``ir_real``'s true heading);
- ``gyro N``: dead reckoning with the heading filter fed by the encoders and a gyro
  emulated on the reference heading (the fakes' CruzCore model, seed N).

With ``--ir-noise`` the readings carry the Sharp noise model (the same draw for every
map). Every map takes the same scans (those the daemon's motion filter takes at the reference
poses) with a heading sigma of 0, so that only the poses differ. The table goes to
stdout; the LAST line is a JSON object with ``pose_err_for_pr50_m`` (per shape and the
median: the largest mean pose error at which occupied precision and recall are both
still >= 0.5, interpolated between the fractions) and ``precision_at_0_5m`` /
``recall_at_0_5m`` (the scores interpolated at a mean pose error of 0.5 m).

    python bench/ir_tolerance.py ../shared/data/intel [--seeds 3] [--scans 5505]
        [--mounts "x,y,yaw_deg;..."] [--ir-noise] [--fractions 0,0.1,...]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.ir_real import find_inputs, headings, mapped, plain_map, true_heading_poses
from hilnav.config import load_config
from hilnav.importers.carmen import emulate, reference_map
from hilnav.services import heading_params, motion_filter_config
from mapping.carmen import load_laser_log
from mapping.grid import GridConfig
from mapping.map_scores import score
from msgs import Pose2D
from numerics.angles import wrap

FRACTIONS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0)


def scaled(traj: np.ndarray, ref: np.ndarray, f: float) -> np.ndarray:
    """The reference plus ``f`` times the trajectory's error (position, wrapped heading)."""
    out = ref.copy()
    out[:, :2] += f * (traj[:, :2] - ref[:, :2])
    out[:, 2] = wrap(ref[:, 2] + f * wrap(traj[:, 2] - ref[:, 2]))
    return out


def crossing(err: list[float], p: list[float], r: list[float], level: float = 0.5) -> float:
    """The largest mean pose error (``err`` rising) at which precision and recall are
    both still >= ``level``, linearly interpolated; NaN if not even at the first."""
    both = [min(a, b) for a, b in zip(p, r, strict=True)]
    if both[0] < level:
        return math.nan
    for k in range(1, len(err)):
        if both[k] < level:
            t = (both[k - 1] - level) / (both[k - 1] - both[k])
            return err[k - 1] + t * (err[k] - err[k - 1])
    return err[-1]


def at(err: list[float], ys: list[float], x: float) -> float:
    """``ys`` interpolated at mean pose error ``x`` (NaN beyond the largest error)."""
    return float(np.interp(x, err, ys)) if err[-1] >= x else math.nan


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path, help="folder of the laser log (or the log itself)")
    ap.add_argument("--mounts", help='IR mounts "x,y,yaw_deg;..." (default: the config\'s)')
    ap.add_argument("--seeds", type=int, default=3, help="gyro error shapes")
    ap.add_argument("--scans", type=int, help="only the first N scans")
    ap.add_argument("--fractions", default=",".join(map(str, FRACTIONS)))
    ap.add_argument("--ir-noise", action="store_true", help="Sharp noise model on the IR")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cfg = load_config(None)
    from hilnav.commands.importer import parse_mounts  # the CLI's --ir-mounts syntax

    mounts = np.array(parse_mounts(args.mounts) if args.mounts else cfg.geometry.ir_mounts_rad())
    fractions = sorted({float(f) for f in args.fractions.split(",")})
    src, ref_log = find_inputs(args.dir)
    log = load_laser_log(src, ref_log).head(args.scans)
    if log.reference is None:
        raise SystemExit(f"{src}: no reference poses (a corrected log is needed)")
    m = cfg.services.mapping
    grid_cfg = GridConfig(resolution_m=m.resolution_m, origin_m=m.origin_m, size_m=m.size_m)
    base = emulate(log, mounts, ir_noise_seed=0 if args.ir_noise else None)
    ref = log.reference
    ref_poses = [Pose2D(*map(float, p)) for p in ref]
    zeros = [0.0] * len(ref)
    ref_map = reference_map(base, m.resolution_m, m.origin_m).with_observed(
        plain_map(base, grid_cfg, ref_poses, zeros, np.arange(len(ref)))
    )
    keep = mapped(base, ref_poses, motion_filter_config(cfg))
    shapes = {"odometry": np.array([[p.x, p.y, p.theta] for p in true_heading_poses(base)])}
    params = heading_params(cfg)
    for seed in range(1, args.seeds + 1):
        run = emulate(log, mounts, gyro_seed=seed, gyro_rate_hz=float(cfg.devices.gyro.rate_hz))
        est = headings(run, params, use_gyro=True)
        shapes[f"gyro {seed}"] = np.array([[e.pose.x, e.pose.y, e.pose.theta] for e in est])
    print(f"{src.name}: {len(log)} scans ({len(keep)} mapped), {len(mounts)} IR mounts")
    print(f"{'error shape':12s} {'f':>5s} {'pose_m':>7s} {'prec':>6s} {'rec':>6s} {'align':>6s}")
    table: dict[str, tuple[list[float], list[float], list[float]]] = {}
    for name, traj in shapes.items():
        errs, ps, rs = [], [], []
        for f in fractions:
            poses = scaled(traj, ref, f)
            grid = plain_map(base, grid_cfg, [Pose2D(*map(float, p)) for p in poses], zeros, keep)
            s = score(grid, ref_map)
            e = float(np.mean(np.hypot(*(poses[keep, :2] - ref[keep, :2]).T)))
            errs.append(e)
            ps.append(s.occupied_precision)
            rs.append(s.occupied_recall)
            print(f"{name:12s} {f:5.2f} {e:7.3f} {s.occupied_precision:6.3f} "
                  f"{s.occupied_recall:6.3f} {s.alignment:6.3f}", flush=True)  # fmt: skip
        table[name] = (errs, ps, rs)

    def med(xs: list[float]) -> float | None:
        xs = [x for x in xs if not math.isnan(x)]
        return round(statistics.median(xs), 4) if xs else None

    cross = {k: crossing(*v) for k, v in table.items()}
    p05 = [at(v[0], v[1], 0.5) for v in table.values()]
    r05 = [at(v[0], v[2], 0.5) for v in table.values()]
    out = {
        "bench": "ir_tolerance",
        "source": src.name,
        "scans": len(log),
        "mounts": len(mounts),
        "seeds": args.seeds,
        "ir_noise": args.ir_noise,
        "pose_err_for_pr50_m": med(list(cross.values())),
        "pose_err_for_pr50_by_shape_m": {
            k: None if math.isnan(v) else round(v, 3) for k, v in cross.items()
        },
        "precision_at_0_5m": med(p05),
        "recall_at_0_5m": med(r05),
        "precision_ref": round(table["odometry"][1][0], 4) if fractions[0] == 0 else None,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
