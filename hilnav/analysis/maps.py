"""Map quality (ir-grid-mapping.txt §4): the last logged map against the floor plan.

The map match ratio of the last ``map`` (foxglove.Grid) against the floor plan named in the
log's "hilnav" metadata (``plan``, or ``--plan``), via mapping.quality.
"""

from __future__ import annotations

import numpy as np

from hilnav.analysis.result import MapSummary
from hilnav.analysis.tracks import RobotLog
from msgs import OccupancyGridMsg


def grid_of_msg(msg: OccupancyGridMsg):  # noqa: ANN201 - mapping.grid.OccupancyGrid
    """A mapping OccupancyGrid (log-odds) from a logged foxglove.Grid."""
    from mapping.export import from_grid_msg
    from mapping.grid import OccupancyGrid

    cells = from_grid_msg(msg).astype(float)
    p = np.clip(cells / 100.0, 0.005, 0.995)
    logodds = np.where(cells < 0, 0.0, np.log(p) - np.log1p(-p))
    res = msg.cell_size.x
    return OccupancyGrid.from_array(logodds, res, (msg.pose.position.x, msg.pose.position.y))


def load_plan(name: str):  # noqa: ANN201 - fakes.world.FloorPlan
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
