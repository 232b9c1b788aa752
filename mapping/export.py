"""Map export: the grid as a foxglove.Grid message and back, a PNG picture, probabilities.

- :func:`to_grid_msg` / :func:`from_grid_msg`: the grid as a ``foxglove.Grid``
  (msgs.OccupancyGridMsg: INT8 occupancy, -1 unknown, 0..100 percent; rows along +y);
- :func:`write_png`: a picture of the grid, north up (white free, black occupied, grey
  205 never observed), written with Pillow;
- :func:`occupancy_probability`: the occupancy probability of every cell of a grid or a
  grid message, nan where never observed.

Map files for nav2's map_server (PGM/PNG + YAML) are in :mod:`mapping.mapfile`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from mapping.grid import OccupancyGrid
from msgs.mapping import (
    NUMERIC_INT8,
    GridPose,
    GridQuaternion,
    GridTime,
    GridVector2,
    GridVector3,
    OccupancyGridMsg,
    PackedElementField,
)

PICTURE_UNKNOWN = 205  # grey of never-observed cells in pictures (map_server's unknown)


def occupancy_probability(src: OccupancyGrid | OccupancyGridMsg) -> np.ndarray:
    """Occupancy probability per cell (rows along +y), nan where never observed.

    A grid's never-observed cells have a log-odds of exactly 0; a message's are -1."""
    if isinstance(src, OccupancyGrid):
        p = src.probability()
        p[src.logodds == 0] = np.nan
        return p
    cells = from_grid_msg(src).astype(np.float64)
    return np.where(cells < 0, np.nan, cells / 100.0)


def write_png(grid: OccupancyGrid | OccupancyGridMsg, path: str | Path, scale: int = 1) -> Path:
    """PNG picture of the grid (white free, black occupied, grey unknown), north up."""
    p = occupancy_probability(grid)
    known = ~np.isnan(p)
    px = np.full(p.shape, PICTURE_UNKNOWN, dtype=np.uint8)
    px[known] = np.round(255.0 * (1.0 - p[known])).astype(np.uint8)
    px = px[::-1]  # image row 0 = top of the map
    if scale > 1:
        px = np.kron(px, np.ones((scale, scale), dtype=np.uint8))
    out = Path(path)
    Image.fromarray(px, "L").save(out, format="PNG")
    return out


def to_grid_msg(grid: OccupancyGrid, stamp_ns: int, frame_id: str = "map") -> OccupancyGridMsg:
    """The grid as a foxglove.Grid message: INT8 occupancy -1 unknown, 0..100 percent."""
    p = grid.probability()
    occ = np.round(p * 100.0).astype(np.int8)
    occ[grid.logodds == 0] = -1
    rows, cols = occ.shape
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return OccupancyGridMsg(
        timestamp=GridTime(sec, nsec),
        frame_id=frame_id,
        pose=GridPose(GridVector3(grid.origin[0], grid.origin[1], 0.0), GridQuaternion()),
        column_count=cols,
        cell_size=GridVector2(grid.resolution, grid.resolution),
        row_stride=cols,
        cell_stride=1,
        fields=(PackedElementField("occupancy", 0, NUMERIC_INT8),),
        data=occ.tobytes(),
    )


def from_grid_msg(msg: OccupancyGridMsg) -> np.ndarray:
    """The INT8 occupancy cells (rows along +y) of a foxglove.Grid written by to_grid_msg."""
    if msg.cell_stride != 1 or msg.column_count <= 0 or msg.row_stride != msg.column_count:
        raise ValueError("grid message is not a packed INT8 occupancy grid")
    data = np.frombuffer(msg.data, dtype=np.int8)
    if data.size % msg.column_count:
        raise ValueError("grid message data is not a whole number of rows")
    return data.reshape(-1, msg.column_count)
