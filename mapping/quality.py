"""Map quality against a true map (ir-grid-mapping.txt §4, the "grid match ratio").

The paper judges a built map by the fraction of grid cells that agree with a true map
drawn from the CAD plan (44 % without data association, 83 % with). Here:

- the true map is rasterised from a floor plan onto exactly the built grid's cells
  (any object with ``rasterize(resolution, origin, shape)`` returning 1 wall / 0 free /
  -1 outside, such as ``fakes.world.FloorPlan``), after an optional rigid transform
  ``map_from_grid`` brings the grid into the plan's frame (nearest-cell resampling);
- **match ratio** = cells known in both maps (built: occupied p > 0.65 or free
  p < 0.196; truth: wall or free) whose states agree, over all cells known in both;
- **precision / recall of occupied cells**: built occupied cells that are true walls,
  true walls seen (known in the built map) that are built occupied; a
  ``tolerance_cells`` > 0 lets an occupied cell count as right within that many cells
  of a true wall (and a wall as found within that many cells of an occupied cell);
- **occupied IoU**: |built occ and true wall| / |built occ or true wall seen| (strict).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np
from scipy.ndimage import binary_dilation

from mapping.grid import OccupancyGrid
from msgs import Pose2D


class Rasterizable(Protocol):
    def rasterize(
        self, resolution: float, origin: tuple[float, float], shape: tuple[int, int]
    ) -> np.ndarray: ...


@dataclass(frozen=True)
class MapQuality:
    match_ratio: float
    known_both: int
    agree: int
    occupied_precision: float
    occupied_recall: float
    occupied_iou: float
    built_occupied: int
    true_walls_seen: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _resample(grid_cells: np.ndarray, grid: OccupancyGrid, map_from_grid: Pose2D) -> np.ndarray:
    """Trinary cells of the grid moved by ``map_from_grid``, on the grid's own lattice."""
    if map_from_grid == Pose2D():
        return grid_cells
    rows, cols = grid_cells.shape
    r, c = np.mgrid[0:rows, 0:cols]
    mx, my = grid.centre_of(r, c)
    # Invert the transform: where in the grid frame does each map-frame cell come from?
    ct, st = math.cos(map_from_grid.theta), math.sin(map_from_grid.theta)
    dx, dy = mx - map_from_grid.x, my - map_from_grid.y
    gx, gy = ct * dx + st * dy, -st * dx + ct * dy
    gr, gc = grid.cell_of(gx, gy)
    ok = grid.inside(gr, gc)
    out = np.full(grid_cells.shape, -1, dtype=np.int8)
    out[ok] = grid_cells[gr[ok], gc[ok]]
    return out


def true_map(grid: OccupancyGrid, plan: Rasterizable) -> np.ndarray:
    """The plan rasterised on the grid's cells: 1 wall, 0 free, -1 outside."""
    return np.asarray(plan.rasterize(grid.resolution, grid.origin, grid.shape), dtype=np.int8)


def compare(
    grid: OccupancyGrid,
    truth: np.ndarray | Rasterizable,
    map_from_grid: Pose2D | None = None,
    tolerance_cells: int = 0,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
) -> MapQuality:
    """Quality of ``grid`` against a true map (array on the grid's cells, or a plan)."""
    t = truth if isinstance(truth, np.ndarray) else true_map(grid, truth)
    if t.shape != grid.shape:
        raise ValueError(f"true map shape {t.shape} differs from the grid's {grid.shape}")
    built = _resample(grid.trinary(occupied_thresh, free_thresh), grid, map_from_grid or Pose2D())
    known = (built >= 0) & (t >= 0)
    agree = known & (built == t)
    b_occ = built == 1
    t_wall = t == 1
    if tolerance_cells > 0:
        st = np.ones((2 * tolerance_cells + 1,) * 2, dtype=bool)
        t_near = binary_dilation(t_wall, structure=st)
        b_near = binary_dilation(b_occ, structure=st)
    else:
        t_near, b_near = t_wall, b_occ
    seen_walls = t_wall & (built >= 0)
    tp_prec = int((b_occ & t_near).sum())
    tp_rec = int((seen_walls & b_near).sum())
    n_b = int(b_occ.sum())
    n_w = int(seen_walls.sum())
    inter = int((b_occ & t_wall).sum())
    union = int((b_occ | seen_walls).sum())
    n_known = int(known.sum())
    return MapQuality(
        match_ratio=float(agree.sum()) / n_known if n_known else 0.0,
        known_both=n_known,
        agree=int(agree.sum()),
        occupied_precision=tp_prec / n_b if n_b else 0.0,
        occupied_recall=tp_rec / n_w if n_w else 0.0,
        occupied_iou=inter / union if union else 0.0,
        built_occupied=n_b,
        true_walls_seen=n_w,
    )
