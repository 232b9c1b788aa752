"""Logged maps: the map of a log at a time, and its quality against the floor plan.

- :func:`logged_map`: a robot's last map (foxglove.Grid) in a log, or the last one at or
  before a time (``hilnav map export``);
- :func:`map_summary`: the map match ratio (ir-grid-mapping.txt §4) of the last map
  against the floor plan named in the log's "hilnav" metadata (``plan``, or ``--plan``),
  via mapping.quality.
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


def map_summary(rl: RobotLog, plan_name: str | None) -> MapSummary | None:
    """Size and known cells of the robot's last map, and its quality against the plan."""
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
    if not plan_name:
        return MapSummary(**size)
    try:
        plan = load_plan(plan_name)
    except ValueError as exc:
        return MapSummary(**size, plan_error=str(exc))
    from mapping.quality import compare

    return MapSummary(**size, plan=plan_name, quality=compare(grid, plan))
