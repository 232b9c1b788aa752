"""Benchmark: the IR grid-mapping experiment of ir-grid-mapping.txt §4 on the simulated Pioneer.

A Pioneer 3-DX with six Sharp GP2Y0A710K0F IR sensors (front and sides, as in the
paper's fig. 2) and a CruzCore gyro drives about 70 m of loops in the paper's 7 x 7 m
room with furniture (FloorPlan ``paper_room``). The IR readings go through the fakes'
own error model (fakes.world.ir_model: curve with near-range ambiguity, voltage noise,
dropouts, 10-bit ADC) and the driver's curve (drivers.sharp) with a 3-sample median, so
the map sees the IrScan messages the real driver would report. The heading is encoder +
gyro (eq. 1-4): ``fusion.heading.HeadingFilter`` with the robot config's noise (the
paper's alpha, beta, gamma per distance and per turn, the systematic terms) and the gyro's
angle random walk, fed the encoder and (bias-calibrated) gyro heading changes
of every 0.1 s scan period, with the daemon's parameters (the robot config's noise).

Two maps are built from the same run: without data association (poses as estimated),
and with sample-based data association (eq. 7-8; with the heading's drift per radian
turned tested on the map, mapping.heading_drift). Both are compared with the true map
rasterised from the plan; PNGs of both next to the truth go to --out (default
bench/out/). The LAST line printed is a JSON object with match_ratio_without_da,
match_ratio_with_da (paper: 0.44 and 0.83), seconds, cell_updates_per_s and more.

    python bench/grid_mapping.py [--seed N] [--distance 70] [--resolution 0.05] [--out DIR]
                                 [--baseline OLD_CHECKOUT [--repeat N]]

The speed figures are wall time (``cell_updates_per_s``) and, because a shared machine's
load moves wall time, CPU time of this process (``cell_updates_per_cpu_s``). The process
runs with the daemon's heap setting (``hilnav.heap``), and so does a baseline's.
``--baseline OLD_CHECKOUT`` runs this script on that checkout's packages in a subprocess
(bench/baseline.py) alternating with our own runs, and prints both side by side: the
maps must agree and the ratios are the speed-up.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

# The code under test: this checkout's, or (HILNAV_BENCH_CODE, set by --baseline) another's.
if __package__ in (None, "") or "HILNAV_BENCH_CODE" in os.environ:
    sys.path.insert(
        0, os.environ.get("HILNAV_BENCH_CODE", str(Path(__file__).resolve().parents[1]))
    )

from drivers.sharp import STATUS_NAMES, SharpCurve
from fakes.world import DiffDriveRobot, GyroErrorModel, IrErrorModel, SlipModel, World
from fusion.heading import HeadingFilter, HeadingParams
from mapping.association import AssociationConfig, SampleAssociation
from mapping.export import write_png
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
from mapping.mapfile import write_map
from mapping.quality import compare, true_map
from msgs import HeadingEstimate, IrScan, Pose2D, wrap_angle

DEG = math.pi / 180.0
T = TypeVar("T")

# Six IR sensors, front and sides (x, y, yaw on the robot): two forward, two diagonal,
# two sideways, on the rim of the Pioneer's ~0.2 m body.
MOUNTS = np.array(
    [
        [0.20, 0.06, 10 * DEG],
        [0.20, -0.06, -10 * DEG],
        [0.16, 0.14, 45 * DEG],
        [0.16, -0.14, -45 * DEG],
        [0.02, 0.19, 90 * DEG],
        [0.02, -0.19, -90 * DEG],
    ]
)

# Loops in paper_room (7 x 7 m; desk NW, shelf SE, cabinet E, table in the middle).
OUTER = [(5.4, 1.5), (5.4, 5.1), (2.2, 5.1), (1.5, 4.4), (1.5, 1.5)]
INNER = [(2.1, 2.1), (5.0, 2.1), (5.0, 4.8), (2.1, 4.8), (2.1, 2.1), (1.5, 1.5)]


@dataclass
class Step:
    """One IR scan with the heading estimate it is mapped with, and the truth."""

    truth: Pose2D
    heading: HeadingEstimate
    scan: IrScan


@dataclass
class Run:
    steps: list[Step]
    distance_m: float
    final_heading_error_deg: float
    final_position_error_m: float
    extra: dict = field(default_factory=dict)


def _route(start: tuple[float, float], distance_m: float) -> list[tuple[float, float]]:
    pts = [start]
    length, loop = 0.0, 0
    while length < distance_m:
        seq = OUTER if loop % 2 == 0 else INNER
        for p in seq:
            length += math.dist(pts[-1], p)
            pts.append(p)
        loop += 1
    return pts[1:]


def _gyro(seed: int, gyro_scale_error: float | None, perfect: bool) -> GyroErrorModel:
    """The CruzCore's error model (no errors at all with ``perfect``)."""
    if perfect:
        gyro = GyroErrorModel(0.0, 0.0, 0.0, 0.0, seed=seed + 100)
    else:
        gyro = GyroErrorModel(seed=seed + 100)
    if gyro_scale_error is not None:
        gyro.scale = 1.0 + gyro_scale_error
    return gyro


def _boot_bias(gyro: GyroErrorModel, dt: float) -> float:
    """Stand still 3 s: the gyro's turn-on bias is calibrated, as a robot does at boot."""
    rates = [gyro.sample(0.0, dt) for _ in range(int(3.0 / dt))]
    return float(np.mean(rates))


def _steer(robot: DiffDriveRobot, target: tuple[float, float], speed_mps: float) -> bool:
    """The operator: command the wheels towards ``target`` on the true pose; False (and
    no command) once within 0.1 m of it."""
    tx, ty = target
    p = robot.pose
    dx, dy = tx - p.x, ty - p.y
    if math.hypot(dx, dy) < 0.1:
        return False
    err = wrap_angle(math.atan2(dy, dx) - p.theta)
    w = max(-0.6, min(0.6, 2.0 * err))
    v = 0.0 if abs(err) > 20 * DEG else speed_mps * max(0.3, math.cos(err))
    base = robot.wheelbase_m
    robot.command_wheels(v - 0.5 * w * base, v + 0.5 * w * base)
    return True


def heading_params(gyro: GyroErrorModel) -> HeadingParams:
    """The daemon's heading filter (the robot config's noise: eq. 4 per distance and per
    turn, and the systematic terms), with the emulated CruzCore's angle random walk."""
    from dataclasses import replace

    from hilnav.config import load_config
    from hilnav.services import heading_params as from_config

    p = from_config(load_config(None))
    return replace(p, gyro_arw_rad_per_sqrt_s=gyro.noise_density_radps_rthz)


class _HeadingInput:
    """Encoder + gyro heading (eq. 1-4): the gyro integrated between scans, the encoders
    differenced, both fed to the heading filter once per scan period."""

    def __init__(self, robot: DiffDriveRobot, gyro: GyroErrorModel, dt: float) -> None:
        self.robot, self.gyro = robot, gyro
        start = robot.pose
        self.bias = _boot_bias(gyro, dt)
        self.filt = HeadingFilter(heading_params(gyro), initial=start)
        self.enc_prev = robot.encoder_m()
        self.gyro_acc = 0.0

    def integrate_gyro(self, dt: float) -> None:
        self.gyro_acc += (self.gyro.sample(self.robot.yaw_rate_radps, dt) - self.bias) * dt

    def estimate(self, stamp_ns: int, period_s: float) -> HeadingEstimate:
        """Step the filter by the encoders' and the gyro's change since the last scan."""
        enc = self.robot.encoder_m()
        dl, dr = enc[0] - self.enc_prev[0], enc[1] - self.enc_prev[1]
        self.enc_prev = enc
        base = self.robot.wheelbase_m
        f = self.filt
        f.step(0.5 * (dl + dr), (dr - dl) / base, self.gyro_acc, period_s)
        self.gyro_acc = 0.0
        return HeadingEstimate(stamp_ns, f.theta, f.variance, Pose2D(f.x, f.y, f.theta))


class _IrBoard:
    """The six IR sensors as the driver reports them: the fakes' error model, then the
    driver's curve on a 3-sample median of the voltages."""

    def __init__(self, seed: int) -> None:
        self.ir = IrErrorModel()
        self.curve: SharpCurve = self.ir.curve
        self.rng = np.random.default_rng(seed + 200)
        self.volts_hist: list[np.ndarray] = []
        self.seq = 0

    def read(self, world: World, stamp_ns: int) -> IrScan:
        true_r = world.ranges("r1", MOUNTS, 12.0)
        counts = self.ir.counts(true_r, self.rng)
        self.volts_hist.append(self.ir.volts(counts))
        self.volts_hist = self.volts_hist[-3:]
        med = np.median(np.stack(self.volts_hist), axis=0)  # the driver's 3-sample median
        rng_m, status = self.curve.range(med)
        scan = IrScan(
            stamp_ns=stamp_ns,
            board_id=0,
            seq=self.seq,
            ranges_m=tuple(float(r) for r in rng_m),
            status=tuple(STATUS_NAMES[int(s)] for s in status),  # type: ignore[misc]
            voltages_v=tuple(float(v) for v in med),
            raw_counts=tuple(int(c) for c in counts),
        )
        self.seq += 1
        return scan


def simulate(
    distance_m: float = 70.0,
    seed: int = 1,
    dt: float = 0.02,
    scan_period_s: float = 0.1,
    speed_mps: float = 0.35,
    gyro_scale_error: float | None = None,
    perfect_odometry: bool = False,
    plan: str = "paper_room",
) -> Run:
    """Drive the loops; return one Step per IR scan (10 Hz)."""
    world = World.from_name(plan, seed=seed)
    slip = SlipModel(0.0, 0.0, 0.0) if perfect_odometry else SlipModel()
    robot = world.add_robot("r1", slip=slip)
    gyro = _gyro(seed, gyro_scale_error, perfect_odometry)
    board = _IrBoard(seed)
    heading = _HeadingInput(robot, gyro, dt)
    route = _route((robot.pose.x, robot.pose.y), distance_m)
    wp = 0
    steps: list[Step] = []
    t_since_scan = 0.0
    stamp = 0
    n_steps_max = int(4 * distance_m / speed_mps / dt) + 1000
    for _ in range(n_steps_max):
        if wp >= len(route) or robot.distance_m >= distance_m:
            break
        if not _steer(robot, route[wp], speed_mps):
            wp += 1
            continue
        world.step(dt)
        stamp += int(dt * 1e9)
        heading.integrate_gyro(dt)
        t_since_scan += dt
        if t_since_scan + 1e-9 < scan_period_s:
            continue
        t_since_scan = 0.0
        est = heading.estimate(stamp, scan_period_s)
        steps.append(Step(robot.pose, est, board.read(world, stamp)))
    return _run(steps, robot.distance_m, gyro, heading.bias)


def _run(steps: list[Step], distance_m: float, gyro: GyroErrorModel, bias: float) -> Run:
    """The run with its final heading and position errors (estimate against truth)."""
    last = steps[-1]
    return Run(
        steps=steps,
        distance_m=distance_m,
        final_heading_error_deg=math.degrees(wrap_angle(last.heading.theta_rad - last.truth.theta)),
        final_position_error_m=math.hypot(
            last.heading.pose.x - last.truth.x, last.heading.pose.y - last.truth.y
        ),
        extra={
            "gyro_scale": gyro.scale,
            "gyro_bias_residual_degps": math.degrees(gyro.bias_radps - bias),
        },
    )


def grid_config(resolution_m: float) -> GridConfig:
    return GridConfig(resolution_m=resolution_m, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0))


def daemon_motion_filter() -> Any:
    """The daemon's motion filter (mapping.motion_filter: the scans the grid takes)."""
    try:
        from hilnav.services import motion_filter_config
        from mapping.motion_filter import MotionFilter
    except ImportError:  # an older checkout's packages (--baseline): every scan
        return _EveryScan()
    from hilnav.config import load_config

    return MotionFilter(motion_filter_config(load_config(None)))


class _EveryScan:
    def keep(self, pose: Any, stamp_ns: int) -> bool:
        return True


def map_without_da(
    run: Run, resolution_m: float = 0.05, inverse: InverseModelConfig | None = None,
    use_truth: bool = False,
) -> OccupancyGrid:  # fmt: skip
    """The plain eq. 5-6 map with the poses as estimated (or the true ones), of the scans
    the daemon's motion filter takes at those poses."""
    grid = OccupancyGrid(grid_config(resolution_m))
    model = IrInverseModel(inverse or InverseModelConfig())
    motion = daemon_motion_filter()
    for s in run.steps:
        pose = s.truth if use_truth else s.heading.pose
        if not motion.keep(pose, s.scan.stamp_ns):
            continue
        sigma = 0.0 if use_truth else math.sqrt(max(s.heading.variance_rad2, 0.0))
        model.integrate(grid, beams_from_scan(pose, sigma, s.scan, MOUNTS))
    return grid


def map_with_da(
    run: Run,
    resolution_m: float = 0.05,
    inverse: InverseModelConfig | None = None,
    config: AssociationConfig | None = None,
    seed: int = 0,
) -> SampleAssociation:
    if config is None:
        from hilnav.config import load_config
        from hilnav.services import association_config

        config = association_config(load_config(None))  # the daemon's
    da = SampleAssociation(
        MOUNTS,
        config,
        grid_config(resolution_m),
        inverse or InverseModelConfig(),
        seed=seed,
    )
    motion = daemon_motion_filter()
    for s in run.steps:
        if motion.keep(s.heading.pose, s.scan.stamp_ns):
            da.step(s.heading, s.scan)
    da.finish()
    return da


def _figure(maps: dict[str, OccupancyGrid], truth: np.ndarray, path: Path, run: Run) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(maps) + 1, figsize=(5 * (len(maps) + 1), 5))
    g0 = next(iter(maps.values()))
    ext0 = (g0.extent[0], g0.extent[2], g0.extent[1], g0.extent[3])
    axes[0].imshow(np.where(truth == 1, 0, np.where(truth == 0, 255, 205)), cmap="gray",
                   origin="lower", extent=ext0, vmin=0, vmax=255)  # fmt: skip
    tx = [s.truth.x for s in run.steps]
    ty = [s.truth.y for s in run.steps]
    axes[0].plot(tx, ty, "g-", lw=0.5)
    axes[0].set_title("true map and path")
    for ax, (name, g) in zip(axes[1:], maps.items(), strict=True):
        ext = (g.extent[0], g.extent[2], g.extent[1], g.extent[3])
        ax.imshow(1.0 - g.probability(), cmap="gray", origin="lower", extent=ext, vmin=0, vmax=1)
        ax.set_title(name)
    for ax in axes:
        ax.set_xlim(-0.5, 7.5)
        ax.set_ylim(-0.5, 7.5)
        ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _timed(fn: Callable[..., T], *args: Any, **kw: Any) -> tuple[T, float, float]:
    """(result, wall seconds, CPU seconds of this process)."""
    w, c = time.perf_counter(), time.process_time()
    out = fn(*args, **kw)
    return out, time.perf_counter() - w, time.process_time() - c


def measure(args: argparse.Namespace) -> dict:
    """One run of the experiment: the result object the bench prints."""
    from fakes.world import load

    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    run, t_sim, _ = _timed(simulate, distance_m=args.distance, seed=args.seed)
    plain, t_plain, c_plain = _timed(map_without_da, run, args.resolution)
    da, t_da, c_da = _timed(map_with_da, run, args.resolution, seed=args.seed)
    plan = load("paper_room")
    ideal = map_without_da(run, args.resolution, use_truth=True)
    q_plain = compare(plain, plan)
    q_da = compare(da.grid, plan)
    q_ideal = compare(ideal, plan)
    truth = true_map(plain, plan)
    write_png(plain, args.out / "grid_without_da.png", scale=2)
    write_png(da.grid, args.out / "grid_with_da.png", scale=2)
    write_map(da.grid, args.out / "grid_with_da")
    _figure({"without DA": plain, "with DA": da.grid, "true poses": ideal}, truth,
            args.out / "grid_mapping.png", run)  # fmt: skip
    outcomes = da.outcome_counts()
    return {
        "bench": "grid_mapping",
        "match_ratio_without_da": round(q_plain.match_ratio, 4),
        "match_ratio_with_da": round(q_da.match_ratio, 4),
        "match_ratio_true_poses": round(q_ideal.match_ratio, 4),
        "occupied_iou_without_da": round(q_plain.occupied_iou, 4),
        "occupied_iou_with_da": round(q_da.occupied_iou, 4),
        "occupied_precision_without_da": round(q_plain.occupied_precision, 4),
        "occupied_precision_with_da": round(q_da.occupied_precision, 4),
        "occupied_recall_without_da": round(q_plain.occupied_recall, 4),
        "occupied_recall_with_da": round(q_da.occupied_recall, 4),
        "paper_match_ratio": [0.44, 0.83],
        "distance_m": round(run.distance_m, 1),
        "scans": len(run.steps),
        "scans_mapped_with_da": len(da.trajectory),
        "final_heading_error_deg": round(run.final_heading_error_deg, 2),
        "final_position_error_m": round(run.final_position_error_m, 3),
        "da_outcomes": outcomes,
        "da_drift_per_rad": round(da.drift_per_rad, 5),
        "da_final_position_error_m": round(
            math.hypot(da.pose.x - run.steps[-1].truth.x, da.pose.y - run.steps[-1].truth.y), 3
        ),
        "resolution_m": args.resolution,
        "seed": args.seed,
        "seconds": round(time.perf_counter() - t0, 2),
        "seconds_simulation": round(t_sim, 2),
        "seconds_map_without_da": round(t_plain, 2),
        "seconds_map_with_da": round(t_da, 2),
        "cpu_seconds_map_without_da": round(c_plain, 2),
        "cpu_seconds_map_with_da": round(c_da, 2),
        "cell_updates": plain.updates,
        "cell_updates_with_da": da.cell_updates,
        "cell_updates_per_s": round(plain.updates / t_plain),
        "cell_updates_per_s_with_da": round(da.cell_updates / t_da),
        "cell_updates_per_cpu_s": round(plain.updates / c_plain),
        "cell_updates_per_cpu_s_with_da": round(da.cell_updates / c_da),
        # Digests of the maps, to see that two codes made the same ones.
        "map_crc_without_da": _crc(plain),
        "map_crc_with_da": _crc(da.grid),
        "load": os.getloadavg()[0],
        "out": str(args.out),
    }


def _crc(grid: OccupancyGrid) -> str:
    import zlib

    geo = np.array([*grid.origin, *grid.shape], dtype=np.float64).tobytes()
    return f"{zlib.crc32(geo + np.ascontiguousarray(grid.logodds).tobytes()):08x}"


RATES = ["cell_updates_per_s", "cell_updates_per_s_with_da", "cell_updates_per_cpu_s",
         "cell_updates_per_cpu_s_with_da"]  # fmt: skip


def _heap_slack() -> None:
    """The daemon's heap setting (hilnav.heap: numpy's per-scan arrays without page
    faults), in this process and, by glibc's environment variable, in a baseline's."""
    try:
        from hilnav.heap import MMAP_THRESHOLD_BYTES, TOP_PAD_BYTES, keep_heap_slack
    except ImportError:  # an older checkout's packages (--baseline): our parent set it
        return
    if keep_heap_slack():
        os.environ["MALLOC_TOP_PAD_"] = str(TOP_PAD_BYTES)
        os.environ["MALLOC_MMAP_THRESHOLD_"] = str(MMAP_THRESHOLD_BYTES)


def main(argv: list[str] | None = None) -> int:
    _heap_slack()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--distance", type=float, default=70.0, help="metres of driving")
    ap.add_argument("--resolution", type=float, default=0.05, help="cell size, m")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "out")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="an older checkout of hilnav, measured by this script in a subprocess "
                    "between our runs (bench/baseline.py)")  # fmt: skip
    ap.add_argument("--repeat", type=int, default=1, help="alternations with --baseline")
    args = ap.parse_args(argv)
    if args.baseline is None:
        result = measure(args)
        print(f"{'':34}{'without DA':>14}{'with DA':>14}")
        for k in ("match_ratio", "cell_updates_per_s", "cell_updates_per_cpu_s"):
            print(f"{k:34}{result[k.replace('ratio', 'ratio_without_da') if 'ratio' in k else k]:>14}"
                  f"{result[k + '_with_da']:>14}")  # fmt: skip
        print(json.dumps(result))
        return 0
    from bench.baseline import merge_best, run_baseline

    best: dict[str, float] = {}
    theirs: dict[str, float] = {}
    ours_last: dict = {}
    old_last: dict = {}
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            old_last = run_baseline(args.baseline, str(Path(__file__).resolve()),
                                    f"--seed={args.seed}", f"--distance={args.distance}",
                                    f"--resolution={args.resolution}", f"--out={tmp}")  # fmt: skip
        merge_best(theirs, old_last, RATES)
        ours_last = measure(args)
        merge_best(best, ours_last, RATES)
    same = all(ours_last[k] == old_last[k] for k in ("map_crc_without_da", "map_crc_with_da"))
    print(f"{'best of ' + str(args.repeat):34}{'baseline':>14}{'this':>14}{'ratio':>8}")
    for k in RATES:
        print(f"{k:34}{theirs[k]:>14.0f}{best[k]:>14.0f}{best[k] / theirs[k]:>8.2f}")
    print(f"same maps (bit for bit): {same}")
    result = dict(ours_last)
    result.update({k: round(v) for k, v in best.items()})
    result["baseline"] = {k: round(v) for k, v in theirs.items()}
    result["baseline_checkout"] = str(args.baseline)
    result["speedup"] = {k: round(best[k] / theirs[k], 2) for k in RATES}
    result["same_maps_as_baseline"] = same
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
