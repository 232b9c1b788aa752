"""Benchmark: the IR grid mapping (ir-grid-mapping §3-4) on a real robot's laser log.

DIR holds a laser log (a CARMEN log with corrected poses, or a scan ``.mat`` with a
corrected CARMEN log of the same run: the Intel data set) or is such a file. The laser's
beams become IR readings at the mounts (``--mounts``, default: the daemon's
``geometry.ir_mounts``) through ``hilnav import carmen``'s emulation (Sharp limits 1-5.5
m; ``--ir-noise``: the Sharp noise model), and the maps are built as the daemon builds
them: heading filter (encoders, or encoders + a gyro emulated on the reference heading
with the fakes' CruzCore model) -> the daemon's motion filter (mapping.motion_filter: the
scans the grid takes) -> IR grid (eq. 5-6), without and with the sample-based data
association (eq. 7-8). Runs:

- reference: the IR map at the reference (corrected) poses;
- true heading: dead reckoning with the reference heading and the odometry's steps, the
  floor of any heading input (its pose error is the odometry's distance error alone);
- encoders only: no gyro, no DA and DA;
- for each of ``--seeds`` seeds (gyro noise, IR noise, DA sampling): no DA and DA.

Each map is scored against the laser map at the reference poses on the cells the IR
sensors observe from those poses (mapping.map_scores: occupied precision / recall within
2 cells, alignment; the paper's match ratio for comparison). Pose error: the mean
distance of the mapped poses (the scans the motion filter took) from the reference,
both starting at its first pose; shape error (``fit_m``): the same after the rigid fit
of the track onto the reference (a turn of the whole track, from a heading error
before the first loop, does not count); relative error (``rel_m``): the mean error of
the track's motions over 10 m of travel, in the frame of their start (Kuemmerle et al.,
2009: what the track gets wrong locally); heading NEES against the reference, at every
scan.
The table goes to stdout; the LAST line is a JSON object with precision_noda,
recall_noda, precision_da_median, recall_da_median, pose_err_noda_m,
pose_err_da_median_m (medians over the seeds, gyro runs), da_worse_runs (seeds where
DA's pose error exceeds no-DA's by more than 1 mm), shape_err_noda_m,
shape_err_da_median_m, rel_err_noda_m, rel_err_da_median_m, shape_worse_runs (the same
count for the shape error), peak_rss_mb, max_step_s (slowest DA
step), max_finish_s (the slowest finish(): the association's pose graph solved and the
map rebuilt once) and more. The DA runs are scored on what finish() returns and on the
association's trajectory after it.

    python bench/ir_real.py ../shared/data/intel [--seeds 8] [--scans 5505]
        [--mounts "0.2,0.05,15;0.2,-0.05,-15;..."] [--ir-noise] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fusion.heading import HeadingFilter, HeadingParams
from hilnav.analysis.geometry import error_after_rigid_fit, relative_error
from hilnav.config import load_config
from hilnav.heap import keep_heap_slack
from hilnav.importers.carmen import EmulatedRun, emulate, reference_map, stream
from hilnav.services import association_config, heading_params, motion_filter_config
from mapping.association import AssociationConfig, SampleAssociation
from mapping.carmen import load_laser_log
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
from mapping.map_scores import MapScore, ReferenceMap, score
from mapping.motion_filter import MotionFilter, MotionFilterConfig
from mapping.se2 import relative
from msgs import HeadingEstimate, Pose2D
from numerics.angles import wrap

DEG = math.pi / 180.0
REL_M = 10.0  # the relative error's distance
CHI2_1_99 = 6.634896601021214


@dataclass
class Result:
    name: str
    score: MapScore
    pose_err_m: float
    final_pose_err_m: float
    shape_err_m: float = math.nan  # after the rigid fit to the reference
    rel_err_m: float = math.nan  # over REL_M of travel
    nees: float = math.nan
    final_sigma_deg: float = math.nan
    final_heading_err_deg: float = math.nan
    max_step_s: float = 0.0
    outcomes: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    finish_s: float = 0.0
    graph: str = ""  # what finish() did with the association's pose graph
    grid: OccupancyGrid | None = None  # the DA map, kept only for --out


def find_inputs(d: Path) -> tuple[Path, Path | None]:
    """(laser log, reference log or None) in a folder, or a file given directly."""
    if d.is_file():
        return d, None
    mats = sorted(d.glob("*.mat"))
    logs = sorted(p for p in d.iterdir() if p.suffix in (".log", ".clf", ".carmen", ".gfs"))
    if mats and logs:
        return mats[0], logs[0]
    if logs:
        return logs[0], None
    raise SystemExit(f"{d}: no CARMEN log (*.log, *.clf) or scan .mat found")


def headings(run: EmulatedRun, params: HeadingParams, use_gyro: bool) -> list[HeadingEstimate]:
    """The heading filter's estimate at each scan (messages in stamp order, as logged)."""
    f = HeadingFilter(params, initial=run.initial_pose)
    out: list[HeadingEstimate] = []
    est = f.estimate()
    for _, _, topic, msg in stream(run):
        if topic == "gyro" and use_gyro:
            f.feed(msg)
        elif topic == "odometry":
            e = f.feed(msg)
            est = e if e is not None else est
        elif topic == "ir":
            out.append(est)
    return out


def mapped(run: EmulatedRun, poses: list[Pose2D], motion: MotionFilterConfig) -> np.ndarray:
    """Indices of the scans the daemon's motion filter takes at ``poses``."""
    f = MotionFilter(motion)
    return np.array([i for i, (p, s) in enumerate(zip(poses, run.scans, strict=True))
                     if f.keep(p, s.stamp_ns)], dtype=int)  # fmt: skip


def plain_map(run: EmulatedRun, grid_cfg: GridConfig, poses, sigmas, keep) -> OccupancyGrid:
    grid = OccupancyGrid(grid_cfg)
    model = IrInverseModel(InverseModelConfig())
    for i in keep:
        model.integrate(grid, beams_from_scan(poses[i], sigmas[i], run.scans[i], run.mounts))
    return grid


def true_heading_poses(run: EmulatedRun) -> list[Pose2D]:
    """Dead reckoning with a perfect heading: each odometry step, in the frame of the
    pose it starts from, composed on the reference heading there. Its pose error is the
    odometry's distance error alone, which no heading input removes."""
    odo = np.array([[o.pose.x, o.pose.y, o.pose.theta] for o in run.odometry])
    ref = run.log.reference
    steps = relative(odo[:-1], odo[1:])
    c, s = np.cos(ref[:-1, 2]), np.sin(ref[:-1, 2])
    dxy = np.column_stack([c * steps[:, 0] - s * steps[:, 1], s * steps[:, 0] + c * steps[:, 1]])
    xy = ref[0, :2] + np.concatenate([np.zeros((1, 2)), np.cumsum(dxy, axis=0)])
    return [Pose2D(float(x), float(y), float(t)) for (x, y), t in zip(xy, ref[:, 2], strict=True)]


def pose_errors(poses: np.ndarray, ref: np.ndarray) -> tuple[float, float, float, float]:
    """(mean, final) distance from the reference (both start at its first pose), the
    mean after the rigid fit of the track onto it, the mean error of its motions over
    REL_M of travel (hilnav.analysis.geometry)."""
    e = np.hypot(poses[:, 0] - ref[:, 0], poses[:, 1] - ref[:, 1])
    return (float(np.mean(e)), float(e[-1]), error_after_rigid_fit(poses, ref),
            relative_error(poses, ref, REL_M))  # fmt: skip


def nees(est: list[HeadingEstimate], ref: np.ndarray) -> tuple[float, float, float]:
    th = np.array([e.theta_rad for e in est])
    var = np.array([e.variance_rad2 for e in est])
    err = wrap(th - ref[:, 2])
    return (
        float(np.mean(err**2 / var)),
        math.degrees(math.sqrt(var[-1])),
        math.degrees(abs(err[-1])),
    )


def run_maps(
    name: str,
    run: EmulatedRun,
    est: list[HeadingEstimate],
    ref_map: ReferenceMap,
    grid_cfg: GridConfig,
    da_seed: int | None,
    da_cfg: AssociationConfig,
    motion: MotionFilterConfig,
) -> Result:
    ref = run.log.reference
    t0 = time.perf_counter()
    n, sig_deg, herr = nees(est, ref)
    poses = [e.pose for e in est]
    keep = mapped(run, poses, motion)
    if da_seed is None:
        sig = [math.sqrt(max(e.variance_rad2, 0.0)) for e in est]
        grid = plain_map(run, grid_cfg, poses, sig, keep)
        traj = np.array([[p.x, p.y, p.theta] for p in poses])[keep]
        r = Result(name, score(grid, ref_map), *pose_errors(traj, ref[keep]), n, sig_deg, herr)
    else:
        da = SampleAssociation(run.mounts, da_cfg, grid_cfg, InverseModelConfig(), seed=da_seed)
        worst = 0.0
        for i in keep:
            ts = time.perf_counter()
            da.step(est[i], run.scans[i])
            worst = max(worst, time.perf_counter() - ts)
        ts = time.perf_counter()
        grid = da.finish()  # with the pose graph: every scan re-posed, the map rebuilt
        fin = time.perf_counter() - ts
        traj = da.trajectory
        r = Result(name, score(grid, ref_map), *pose_errors(traj, ref[keep]), n, sig_deg, herr,
                   worst, da.outcome_counts())  # fmt: skip
        r.grid, r.finish_s, r.graph = grid, fin, getattr(da, "graph_outcome", "")
    r.seconds = time.perf_counter() - t0
    return r


def row(r: Result) -> str:
    s = r.score
    oc = r.outcomes
    acc = f"{oc.get('accepted', 0)}/{sum(oc.values())}" if oc else "-"
    return (f"{r.name:18s} {s.occupied_precision:5.3f} {s.occupied_recall:5.3f} "
            f"{s.alignment:5.3f} {s.match_ratio:5.3f} {r.pose_err_m:7.3f} {r.final_pose_err_m:7.3f} "
            f"{r.shape_err_m:7.3f} {r.rel_err_m:6.3f} "
            f"{r.nees:8.2f} {r.final_sigma_deg:7.1f} {r.final_heading_err_deg:7.1f} "
            f"{acc:>7s} {r.max_step_s:6.3f} {r.seconds:6.1f}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path, help="folder of the laser log (or the log itself)")
    ap.add_argument("--mounts", help='IR mounts "x,y,yaw_deg;..." (default: the config\'s)')
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--scans", type=int, help="only the first N scans")
    ap.add_argument("--ir-noise", action="store_true", help="Sharp noise model on the IR")
    ap.add_argument("--reference", type=Path, help="corrected log (default: found in DIR)")
    ap.add_argument("--no-encoders-only", action="store_true", help="skip the encoder runs")
    ap.add_argument("--out", type=Path, help="write the maps as PNGs here")
    args = ap.parse_args(argv)
    keep_heap_slack()  # the daemon's heap setting (numpy's per-scan arrays, no page faults)
    t_all = time.perf_counter()
    cfg = load_config(None)
    from hilnav.commands.importer import parse_mounts  # the CLI's --ir-mounts syntax

    mounts = np.array(parse_mounts(args.mounts) if args.mounts else cfg.geometry.ir_mounts_rad())
    src, ref_log = find_inputs(args.dir)
    ref_log = args.reference or ref_log
    log = load_laser_log(src, ref_log).head(args.scans)
    if log.reference is None:
        raise SystemExit(f"{src}: no reference poses (a corrected log is needed)")
    m = cfg.services.mapping
    grid_cfg = GridConfig(resolution_m=m.resolution_m, origin_m=m.origin_m, size_m=m.size_m)
    da_cfg = association_config(cfg)
    params = heading_params(cfg)
    base = emulate(log, mounts, ir_noise_seed=0 if args.ir_noise else None)
    laser = reference_map(base, m.resolution_m, m.origin_m)
    motion = motion_filter_config(cfg)
    ref_poses = [Pose2D(*map(float, p)) for p in log.reference]
    every = np.arange(len(ref_poses))
    zeros = [0.0] * len(ref_poses)
    # The cells scored: those the IR sensors observe from the reference poses, every scan.
    ref_map = laser.with_observed(plain_map(base, grid_cfg, ref_poses, zeros, every))
    ideal = plain_map(base, grid_cfg, ref_poses, zeros, mapped(base, ref_poses, motion))
    results = [Result("reference poses", score(ideal, ref_map), 0.0, 0.0, 0.0, 0.0)]
    true_th = true_heading_poses(base)
    keep = mapped(base, true_th, motion)
    traj = np.array([[p.x, p.y, p.theta] for p in true_th])[keep]
    floor = Result("true heading", score(plain_map(base, grid_cfg, true_th, zeros, keep), ref_map),
                   *pose_errors(traj, log.reference[keep]))  # fmt: skip
    print(f"{src.name}: {len(log)} scans, {log.path_length_m():.0f} m driven, "
          f"{len(mounts)} IR mounts, reference: {log.reference_source}")  # fmt: skip
    print(f"{'run':18s} {'prec':>5s} {'rec':>5s} {'align':>5s} {'match':>5s} {'pose_m':>7s} "
          f"{'final_m':>7s} {'fit_m':>7s} {'rel_m':>6s} {'NEES':>8s} {'sig_deg':>7s} {'err_deg':>7s} {'acc':>7s} "
          f"{'step_s':>6s} {'sec':>6s}")  # fmt: skip
    print(row(results[0]), flush=True)
    print(row(floor), flush=True)
    if not args.no_encoders_only:
        est = headings(base, params, use_gyro=False)
        for name, seed in (("encoders no DA", None), ("encoders DA", 0)):
            results.append(run_maps(name, base, est, ref_map, grid_cfg, seed, da_cfg, motion))
            print(row(results[-1]), flush=True)
    noda, da = [], []
    for seed in range(1, args.seeds + 1):
        run = emulate(log, mounts, ir_noise_seed=seed if args.ir_noise else None, gyro_seed=seed,
                      gyro_rate_hz=float(cfg.devices.gyro.rate_hz))  # fmt: skip
        est = headings(run, params, use_gyro=True)
        noda.append(run_maps(f"gyro {seed} no DA", run, est, ref_map, grid_cfg, None, da_cfg,
                             motion))  # fmt: skip
        print(row(noda[-1]), flush=True)
        da.append(run_maps(f"gyro {seed} DA", run, est, ref_map, grid_cfg, seed, da_cfg, motion))
        print(row(da[-1]), flush=True)
        if da[-1].graph:
            print(f"{'':18s} pose graph: {da[-1].graph}", flush=True)
        if args.out is not None:
            from mapping.export import write_png

            args.out.mkdir(parents=True, exist_ok=True)
            write_png(da[-1].grid, args.out / f"ir_real_da_{seed}.png", scale=1)  # type: ignore[arg-type]
        da[-1].grid = None
    results += noda + da

    def med(xs):
        xs = list(xs)
        return statistics.median(xs) if xs else math.nan

    # Worse: by more than a millimetre (DA's dead reckoning re-composes the same steps).
    worse = sum(d.pose_err_m > n.pose_err_m + 1e-3 for n, d in zip(noda, da, strict=True))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    enc = {r.name: r for r in results}
    out = {
        "bench": "ir_real",
        "source": src.name,
        "scans": len(log),
        "distance_m": round(log.path_length_m(), 1),
        "mounts": len(mounts),
        "seeds": args.seeds,
        "ir_noise": args.ir_noise,
        "precision_ref": round(results[0].score.occupied_precision, 4),
        "recall_ref": round(results[0].score.occupied_recall, 4),
        "pose_err_true_heading_m": round(floor.pose_err_m, 3),
        "shape_err_true_heading_m": round(floor.shape_err_m, 3),
        "rel_err_true_heading_m": round(floor.rel_err_m, 3),
        "precision_true_heading": round(floor.score.occupied_precision, 4),
        "recall_true_heading": round(floor.score.occupied_recall, 4),
        "precision_noda": round(med(r.score.occupied_precision for r in noda), 4),
        "recall_noda": round(med(r.score.occupied_recall for r in noda), 4),
        "precision_da_median": round(med(r.score.occupied_precision for r in da), 4),
        "recall_da_median": round(med(r.score.occupied_recall for r in da), 4),
        "alignment_noda": round(med(r.score.alignment for r in noda), 4),
        "alignment_da_median": round(med(r.score.alignment for r in da), 4),
        "match_ratio_noda": round(med(r.score.match_ratio for r in noda), 4),
        "match_ratio_da_median": round(med(r.score.match_ratio for r in da), 4),
        "pose_err_noda_m": round(med(r.pose_err_m for r in noda), 3),
        "pose_err_da_median_m": round(med(r.pose_err_m for r in da), 3),
        "pose_err_da_max_m": round(max((r.pose_err_m for r in da), default=math.nan), 3),
        "shape_err_noda_m": round(med(r.shape_err_m for r in noda), 3),
        "shape_err_da_median_m": round(med(r.shape_err_m for r in da), 3),
        "rel_err_noda_m": round(med(r.rel_err_m for r in noda), 3),
        "rel_err_da_median_m": round(med(r.rel_err_m for r in da), 3),
        "shape_worse_runs": sum(
            d.shape_err_m > n.shape_err_m + 1e-3 for n, d in zip(noda, da, strict=True)
        ),  # fmt: skip
        "da_worse_runs": worse,
        "nees_gyro_median": round(med(r.nees for r in noda), 3),
        "accepted_median": med(r.outcomes.get("accepted", 0) for r in da),
        "peak_rss_mb": round(peak, 1),
        "max_step_s": round(max(r.max_step_s for r in results), 3),
        "max_finish_s": round(max(r.finish_s for r in results), 3),
        "graph_reposed_runs": sum(r.graph.startswith("re-posed") for r in da),
        "seconds": round(time.perf_counter() - t_all, 1),
    }
    if "encoders no DA" in enc:
        e = enc["encoders no DA"]
        out.update({
            "pose_err_encoders_m": round(e.pose_err_m, 3),
            "pose_err_encoders_da_m": round(enc["encoders DA"].pose_err_m, 3),
            "nees_encoders": round(e.nees, 3),
            "final_sigma_encoders_deg": round(e.final_sigma_deg, 1),
            "final_heading_err_encoders_deg": round(e.final_heading_err_deg, 1),
            "encoders_heading_lost": bool(3 * e.final_sigma_deg >= 90.0),
        })  # fmt: skip
    # No seeds: the medians are undefined (null, not JSON's missing NaN).
    print(json.dumps({k: None if isinstance(v, float) and math.isnan(v) else v
                      for k, v in out.items()}))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
