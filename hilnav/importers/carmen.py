"""``hilnav import carmen``: a real robot's laser log as a hilnav log with emulated IR sensors.

Loads a CARMEN text log or a scan ``.mat`` file (:func:`mapping.carmen.load_laser_log`;
``reference``: a corrected log of the same run whose keyframes give the reference poses)
and turns it into the messages the daemon's robot would have logged (robot ``--robot``,
log time = stamp = the data set's clock):

| topic | message | from |
|---|---|---|
| ``/<robot>/odometry`` | msgs.RobotOdometry | the raw odometry at each scan |
| ``/<robot>/ir`` | msgs.IrScan | the laser's beams at the IR mounts (fakes.world.laser_ir): Sharp limits 1-5.5 m, optional noise model (seeded) |
| ``/<robot>/gyro`` | msgs.GyroSample | optional: a gyro emulated on the reference heading with the fakes' CruzCore error model (seeded) |
| ``/<robot>/truth`` | msgs.GroundTruth | the reference (corrected) pose at each scan |
| ``/<robot>/reference_map`` | foxglove.Grid | once: the laser map at the reference poses (mapping.map_scores.laser_map) |

The "hilnav" metadata holds the robot config the replay runs with (``config_toml``: the
IR mounts, the initial pose = the first reference pose, the gyro on or off, no GPS, no
CP localization) and ``pipeline = "daemon"``. With a gyro, each odometry message is
stamped one gyro period before its scan, so the heading of that odometry is out (the
daemon's arrival rule holds odometry until a newer gyro sample) when the scan is mapped.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mapping.laser_log import LaserLog
from msgs import GroundTruth, GyroSample, IrScan, Pose2D, RobotOdometry, wrap_angle

DEG = math.pi / 180.0


@dataclass
class EmulatedRun:
    """A laser log turned into the messages of a robot with IR sensors."""

    log: LaserLog
    mounts: np.ndarray  # (K, 3) x, y, yaw rad
    odometry: list[RobotOdometry]
    scans: list[IrScan]
    truth: list[GroundTruth]
    gyro: list[GyroSample] = field(default_factory=list)
    true_ir_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def initial_pose(self) -> Pose2D:
        """Where the estimates start: the first reference pose, else the first odometry."""
        p = self.truth[0].pose if self.truth else Pose2D(*map(float, self.log.odom[0]))
        return p


def _stamps(t_s: np.ndarray) -> np.ndarray:
    """Integer ns, strictly increasing (ties 1 us apart)."""
    ns = np.round(np.asarray(t_s) * 1e9).astype(np.int64)
    for i in range(1, len(ns)):
        if ns[i] <= ns[i - 1]:
            ns[i] = ns[i - 1] + 1000
    return ns


def emulate(
    log: LaserLog,
    mounts: np.ndarray,
    robot: str = "intel",
    ir_noise_seed: int | None = None,
    gyro_seed: int | None = None,
    gyro_rate_hz: float = 100.0,
    median_window: int = 3,
) -> EmulatedRun:
    """The messages of ``log`` for a robot with IR sensors at ``mounts`` (module doc)."""
    from fakes.world import GyroErrorModel, IrErrorModel
    from fakes.world.gyro_model import gyro_from_heading
    from fakes.world.laser_ir import LaserIrBoard, ir_ranges_from_laser

    mounts = np.atleast_2d(np.asarray(mounts, dtype=float))
    true_ir = ir_ranges_from_laser(log.ranges, log.angles, log.max_range_m, mounts,
                                   log.laser_on_robot)  # fmt: skip
    noise = IrErrorModel() if ir_noise_seed is not None else None
    board = LaserIrBoard(len(mounts), noise, median_window, seed=ir_noise_seed or 0)
    scan_ns = _stamps(log.t_s)
    lead_ns = int(round(1e9 / gyro_rate_hz)) + 1_000_000 if gyro_seed is not None else 0
    scans = [board.scan(r, int(s)) for r, s in zip(true_ir, scan_ns, strict=True)]
    odo = []
    prev = None
    for i, (s, p) in enumerate(zip(scan_ns, log.odom, strict=True)):
        stamp = int(s) - lead_ns if i else int(s)
        stamp = max(stamp, odo[-1].stamp_ns + 1000) if odo else stamp
        v = w = 0.0
        moving = False
        if prev is not None:
            dt = max((stamp - prev[0]) * 1e-9, 1e-3)
            ds = math.hypot(p[0] - prev[1][0], p[1] - prev[1][1])
            dth = wrap_angle(float(p[2] - prev[1][2]))
            v, w = ds / dt, dth / dt
            moving = ds > 0.0 or dth != 0.0
        pose = Pose2D(float(p[0]), float(p[1]), wrap_angle(float(p[2])))
        odo.append(RobotOdometry(stamp, pose, v, v, v, w, 12.0, moving, True))
        prev = (stamp, p)
    truth = []
    gyro: list[GyroSample] = []
    ref = log.reference
    if ref is not None:
        ok = np.all(np.isfinite(ref), axis=1)
        truth = [GroundTruth(int(s), robot, Pose2D(float(p[0]), float(p[1]), wrap_angle(float(p[2]))))
                 for s, p, k in zip(scan_ns, ref, ok, strict=True) if k]  # fmt: skip
        if gyro_seed is not None and ok.sum() >= 2:
            tg, rates, angle = gyro_from_heading(
                log.t_s[ok], ref[ok, 2], GyroErrorModel(seed=gyro_seed), gyro_rate_hz
            )
            gns = _stamps(tg)
            gyro = [GyroSample(int(s), float(r), float(a), wrap_angle(float(a)))
                    for s, r, a in zip(gns, rates, angle, strict=True)]  # fmt: skip
    elif gyro_seed is not None:
        raise ValueError(f"{log.source}: no reference poses to emulate a gyro from")
    return EmulatedRun(log, mounts, odo, scans, truth, gyro, true_ir)


def reference_map(run: EmulatedRun, resolution_m: float, origin_m: tuple[float, float]):
    """The laser map at the reference poses (mapping.map_scores.laser_map), or None."""
    from mapping.map_scores import laser_map

    log = run.log
    if log.reference is None or not np.isfinite(log.reference).all(axis=1).any():
        return None
    return laser_map(log.reference, log.ranges, log.angles, log.max_range_m, resolution_m,
                     origin_m, log.laser_on_robot)  # fmt: skip


def grid_of_reference(ref: Any):
    """A log-odds OccupancyGrid holding a ReferenceMap's cells (wall +4, free -4)."""
    from mapping.grid import OccupancyGrid

    lo = np.where(ref.cells == 1, 4.0, np.where(ref.cells == 0, -4.0, 0.0))
    return OccupancyGrid.from_array(lo, ref.resolution, ref.origin)


def config_toml(run: EmulatedRun, robot: str, gyro_rate_hz: float = 100.0) -> str:
    """The robot config of the imported log (see the module doc)."""
    p = run.initial_pose
    mounts = ", ".join(f"[{x:.4f}, {y:.4f}, {yaw / DEG:.3f}]" for x, y, yaw in run.mounts)
    gyro = "true" if run.gyro else "false"
    return "\n".join([
        f'name = "{robot}"',
        f"initial_pose = [{p.x:.6f}, {p.y:.6f}, {p.theta / DEG:.6f}]",
        "[geometry]",
        f"ir_mounts = [{mounts}]",
        "[devices.gyro]",
        f"enabled = {gyro}",
        f"rate_hz = {int(round(gyro_rate_hz))}",
        "[devices.gps]",
        "enabled = false",
        "[services.localization]",
        "enabled = false",
        "[services.mapping]",
        "publish_every_s = 10.0",
        "",
    ])  # fmt: skip


def stream(run: EmulatedRun) -> Iterator[tuple[int, int, str, Any]]:
    """(stamp, order, topic, message) of the run, merged in stamp order."""

    def s(topic: str, order: int, msgs: list) -> Iterator[tuple[int, int, str, Any]]:
        for m in msgs:
            yield (m.stamp_ns, order, topic, m)

    return heapq.merge(
        s("gyro", 0, run.gyro),
        s("odometry", 1, run.odometry),
        s("truth", 2, run.truth),
        s("ir", 3, run.scans),
    )


def import_carmen(
    path: str | Path,
    out: str | Path,
    robot: str = "intel",
    reference: str | Path | None = None,
    mounts: np.ndarray | None = None,
    ir_noise_seed: int | None = None,
    gyro_seed: int | None = None,
    scans: int | None = None,
    poses: str = "auto",
    compression: str = "zstd",
) -> Any:
    """Write the laser log at ``path`` as the MCAP log ``out`` (module doc)."""
    from hilnav.config import load_config
    from hilnav.importers.report import ImportReport
    from hilnav.log.writer import LogWriter
    from mapping.carmen import load_laser_log
    from mapping.export import to_grid_msg

    cfg = load_config(None)
    if mounts is None:
        mounts = np.asarray(cfg.geometry.ir_mounts_rad(), dtype=float)
    gyro_rate = float(cfg.devices.gyro.rate_hz)
    log = load_laser_log(path, reference, poses).head(scans)  # type: ignore[arg-type]
    run = emulate(log, mounts, robot, ir_noise_seed, gyro_seed, gyro_rate,
                  cfg.devices.ir.median_window)  # fmt: skip
    m = cfg.services.mapping
    ref = reference_map(run, m.resolution_m, m.origin_m)
    rep = ImportReport(str(path), str(out), robot)
    rep.extra = {"loader": dict(sorted(log.counts.items())), "reference": log.reference_source,
                 "distance_m": round(log.path_length_m(), 1)}  # fmt: skip
    meta = {
        "robot": robot,
        "dataset": "carmen",
        "pipeline": "daemon",
        "source": log.source,
        "reference": log.reference_source or "none",
        "plan": "",
        "ir_noise_seed": "" if ir_noise_seed is None else str(ir_noise_seed),
        "gyro_seed": "" if gyro_seed is None else str(gyro_seed),
        "config_toml": config_toml(run, robot, gyro_rate),
    }
    with LogWriter(out, compression=compression, metadata=meta, wall_clock=False) as w:
        first = True
        for stamp, _, topic, msg in stream(run):
            if first:
                first = False
                rep.first_ns = stamp
                if ref is not None:
                    w.write(
                        f"/{robot}/reference_map", to_grid_msg(grid_of_reference(ref), stamp), stamp
                    )
                    rep.counts["reference_map"] += 1
            w.write(f"/{robot}/{topic}", msg, stamp)
            rep.counts[topic] += 1
            rep.last_ns = stamp
    return rep
