"""Logged maps: the map of a log at a time, and its quality against the floor plan.

- :func:`logged_map`: a robot's last map (foxglove.Grid) in a log, or the last one at or
  before a time (``hilnav map export``);
- :func:`map_summary`: the last map against the floor plan named in the log's "hilnav"
  metadata (``plan``, or ``--plan``), or else against the log's ``reference_map`` (an
  imported data set's laser map at its reference poses): the scores of
  mapping.map_scores (occupied precision / recall, alignment, on the cells the IR sensors
  observe from the reference poses: the map the log's IR scans make at the truth), and
  the paper's match ratio (mapping.quality) for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hilnav.analysis.result import MapSummary
from hilnav.analysis.tracks import NS, RobotLog
from hilnav.log.reader import RawRecord, ReadStats, decode_record, iter_raw
from hilnav.topics import split_log_topic
from msgs import OccupancyGridMsg, schema_name


@dataclass(frozen=True)
class LoggedMap:
    """One map of a log: whose, when (log time; seconds after the log's first record)."""

    robot: str
    log_time_ns: int
    at_s: float
    msg: OccupancyGridMsg


def logged_map(path: str | Path, robot: str | None = None, at_s: float | None = None) -> LoggedMap:
    """The last map of ``robot`` in the log, or the last one logged at or before ``at_s``
    seconds after the log's first record. ValueError when there is none, or when the log
    holds the maps of several robots and ``robot`` does not choose one."""
    grid_schema = schema_name(OccupancyGridMsg)
    start: int | None = None
    last: dict[str, RawRecord] = {}  # robot -> its last qualifying raw record
    first_s: dict[str, float] = {}
    for r in iter_raw(path):
        start = r.log_time_ns if start is None else min(start, r.log_time_ns)
        who, _kind = split_log_topic(r.topic)
        if r.schema_name != grid_schema or (robot is not None and who != robot):
            continue
        t_s = (r.log_time_ns - start) / NS
        first_s.setdefault(who, t_s)
        if at_s is None or t_s <= at_s:
            last[who] = r
    if not first_s:
        raise ValueError(
            f"{path}: no map" + (f" of robot {robot!r}" if robot else "") + " in the log"
        )
    if robot is None and len(first_s) > 1:
        raise ValueError(
            f"{path} holds the maps of {', '.join(sorted(first_s))}: choose one (--robot)"
        )
    who = robot if robot is not None else next(iter(first_s))
    rec = last.get(who)
    if rec is None:
        raise ValueError(
            f"no map of {who} at or before {at_s} s (the first is at {first_s[who]:.3f} s)"
        )
    stats = ReadStats()
    m = decode_record(rec, stats)
    if m is None:
        raise ValueError(f"{path}: the map at {rec.log_time_ns} ns does not decode: {stats.errors}")
    assert start is not None
    return LoggedMap(who, m.log_time_ns, (m.log_time_ns - start) / NS, m.msg)


def grid_of_msg(msg: OccupancyGridMsg):
    """A mapping OccupancyGrid (log-odds) from a logged foxglove.Grid."""
    from mapping.export import from_grid_msg
    from mapping.grid import OccupancyGrid

    cells = from_grid_msg(msg).astype(float)
    p = np.clip(cells / 100.0, 0.005, 0.995)
    logodds = np.where(cells < 0, 0.0, np.log(p) - np.log1p(-p))
    res = msg.cell_size.x
    return OccupancyGrid.from_array(logodds, res, (msg.pose.position.x, msg.pose.position.y))


def load_plan(name: str):
    """A floor plan of fakes.world by name (ValueError for an unknown one)."""
    from fakes.world import floorplan

    return floorplan.load(name)


def reference_of_msg(msg: OccupancyGridMsg):
    """A mapping.map_scores.ReferenceMap from a logged reference map (walls p > 0.65,
    free p < 0.196)."""
    from mapping.export import from_grid_msg
    from mapping.map_scores import ReferenceMap

    c = from_grid_msg(msg)
    cells = np.where(c > 65, 1, np.where((c >= 0) & (c < 19.6), 0, -1)).astype(np.int8)
    return ReferenceMap(cells, msg.cell_size.x, (msg.pose.position.x, msg.pose.position.y))


def mounts_of(meta: dict[str, str]) -> np.ndarray:
    """The IR mounts (K, 3; yaw rad) of the config recorded in the log (else the defaults)."""
    from hilnav.replay.resolve import resolve_config

    cfg, _ = resolve_config(None, meta)
    return np.asarray(cfg.geometry.ir_mounts_rad(), dtype=float)


def observed_grid(rl: RobotLog, mounts: np.ndarray, like):
    """The IR map of the robot's scans at the truth (plain fig. 4 model, no cone), on the
    lattice of the OccupancyGrid ``like``; None without IR scans and truth."""
    from hilnav.analysis.geometry import interp_pose
    from mapping.grid import GridConfig, OccupancyGrid
    from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
    from msgs import Pose2D

    if not rl.ir or len(rl.truth) < 2 or mounts.shape[0] != len(rl.ir[0].status):
        return None
    rt, rx, ry, rth = rl.truth.arrays()
    t = np.array([s.stamp_ns for s in rl.ir], dtype=np.int64)
    qx, qy, qth, ok = interp_pose(rt, rx, ry, rth, t)
    cfg = GridConfig(resolution_m=like.resolution, origin_m=like.origin, size_m=(1.0, 1.0))
    grid = OccupancyGrid(cfg)
    model = IrInverseModel(InverseModelConfig(use_heading_uncertainty=False))
    for i, s in enumerate(rl.ir):
        if ok[i] and len(s.status) == len(mounts):
            pose = Pose2D(float(qx[i]), float(qy[i]), float(qth[i]))
            model.integrate(grid, beams_from_scan(pose, 0.0, s, mounts))
    return grid


def map_summary(
    rl: RobotLog, plan_name: str | None, meta: dict[str, str] | None = None
) -> MapSummary | None:
    """Size and known cells of the robot's last map, and its quality against the plan
    or the log's reference map."""
    if rl.last_map is None:
        return None
    grid = grid_of_msg(rl.last_map)
    cells = grid.trinary()
    size = {
        "maps_logged": rl.maps,
        "rows": int(grid.shape[0]),
        "cols": int(grid.shape[1]),
        "resolution_m": grid.resolution,
        "known_cells": int((cells >= 0).sum()),
        "occupied_cells": int((cells == 1).sum()),
    }
    from mapping.map_scores import ReferenceMap, score
    from mapping.quality import compare

    if plan_name:
        try:
            plan = load_plan(plan_name)
        except ValueError as exc:
            return MapSummary(**size, plan_error=str(exc))
        from mapping.quality import true_map

        ref = ReferenceMap(true_map(grid, plan), grid.resolution, grid.origin)
        ref = _observed(ref, rl, meta)
        return MapSummary(**size, plan=plan_name, quality=compare(grid, plan),
                          scores=score(grid, ref), scored_against="plan")  # fmt: skip
    if rl.reference_map is None:
        return MapSummary(**size)
    ref = _observed(reference_of_msg(rl.reference_map), rl, meta)
    return MapSummary(**size, scores=score(grid, ref), scored_against="reference_map")


def _observed(ref, rl: RobotLog, meta: dict[str, str] | None):
    """``ref`` with the cells the IR scans observe from the truth (as is without them)."""
    from mapping.grid import OccupancyGrid

    like = OccupancyGrid.from_array(np.zeros((1, 1)), ref.resolution, ref.origin)
    seen = observed_grid(rl, mounts_of(meta or {}), like)
    return ref.with_observed(seen) if seen is not None else ref
