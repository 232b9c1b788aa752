"""Log-odds occupancy grid (ir-grid-mapping.txt eq. 5), clamped, growing on demand.

Eq. (5) is the Bayesian update of every cell's occupancy odds with the inverse sensor
model p(m_i | x_t, z_t) of the current reading, assuming a prior of 0.5. In log-odds
l = log(p / (1 - p)) it becomes a sum, l_t = l_{t-1} + log(p_inv / (1 - p_inv)), which is
what :meth:`OccupancyGrid.add` does for a batch of cells; the result is clamped to
[l_min, l_max] so that a cell can still change its mind (and no value overflows).

Cell (row, col) covers x in [ox + col*res, ox + (col+1)*res), y in [oy + row*res, ...):
row 0 is at the origin's y (the ROS map_server and FloorPlan.rasterize convention). The
grid grows in whole chunks, keeping every cell's world position, whenever an update
reaches outside it (:meth:`ensure`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def logit(p: float) -> float:
    """log(p / (1 - p)) of a probability in (0, 1)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"probability must be in (0, 1), got {p}")
    return math.log(p) - math.log1p(-p)


@dataclass(frozen=True)
class GridConfig:
    """Geometry and clamping of a grid.

    resolution_m: cell side; origin_m: world position of the corner of cell (0, 0);
    size_m: initial width and height; grow_chunk_m: the grid grows by at least this
    on a side it must extend; l_min/l_max: log-odds clamp (+-4 is p 0.018..0.982).
    """

    resolution_m: float = 0.05
    origin_m: tuple[float, float] = (-5.0, -5.0)
    size_m: tuple[float, float] = (10.0, 10.0)
    grow_chunk_m: float = 2.0
    l_min: float = -4.0
    l_max: float = 4.0
    max_cells: int = 25_000_000

    def __post_init__(self) -> None:
        if not (self.resolution_m > 0 and math.isfinite(self.resolution_m)):
            raise ValueError(f"grid resolution_m must be > 0, got {self.resolution_m}")
        if self.size_m[0] <= 0 or self.size_m[1] <= 0:
            raise ValueError(f"grid size_m must be positive, got {self.size_m}")
        if not self.l_min < 0 < self.l_max:
            raise ValueError(f"grid clamp needs l_min < 0 < l_max, got {self.l_min}, {self.l_max}")
        if self.grow_chunk_m < 0:
            raise ValueError("grid grow_chunk_m must be >= 0")


class OccupancyGrid:
    """A 2-D array of log-odds (float32) with a world origin and a resolution."""

    def __init__(self, config: GridConfig | None = None) -> None:
        self.config = config or GridConfig()
        c = self.config
        self.resolution = float(c.resolution_m)
        self.origin = (float(c.origin_m[0]), float(c.origin_m[1]))
        rows = max(1, int(math.ceil(c.size_m[1] / self.resolution - 1e-9)))
        cols = max(1, int(math.ceil(c.size_m[0] / self.resolution - 1e-9)))
        self.logodds = np.zeros((rows, cols), dtype=np.float32)
        self.updates = 0  # cell updates applied so far

    # -- geometry ---------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.logodds.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in metres."""
        rows, cols = self.shape
        return (
            self.origin[0],
            self.origin[1],
            self.origin[0] + cols * self.resolution,
            self.origin[1] + rows * self.resolution,
        )

    def cell_of(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of world points (may lie outside the grid)."""
        col = np.floor((np.asarray(x) - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y) - self.origin[1]) / self.resolution).astype(np.int64)
        return row, col

    def centre_of(self, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World centre (x, y) of cells."""
        return (
            self.origin[0] + (np.asarray(col) + 0.5) * self.resolution,
            self.origin[1] + (np.asarray(row) + 0.5) * self.resolution,
        )

    def inside(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        rows, cols = self.shape
        return (row >= 0) & (row < rows) & (col >= 0) & (col < cols)

    def _growth(self, xmin: float, ymin: float, xmax: float, ymax: float) -> tuple[int, ...]:
        """(left, down, right, up): the cells to add on each side to hold the box."""
        if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)):
            raise ValueError("grid ensure(): box must be finite")
        gx0, gy0, gx1, gy1 = self.extent
        if xmin >= gx0 and ymin >= gy0 and xmax < gx1 and ymax < gy1:
            return (0, 0, 0, 0)
        res = self.resolution
        chunk = int(math.ceil(self.config.grow_chunk_m / res))

        def need(lo_gap: float) -> int:
            return 0 if lo_gap <= 0 else int(math.ceil(lo_gap / res)) + chunk

        return (need(gx0 - xmin), need(gy0 - ymin), need(xmax - gx1 + res), need(ymax - gy1 + res))

    def fits(self, xmin: float, ymin: float, xmax: float, ymax: float) -> bool:
        """Whether the box is inside or the grid may grow to hold it (``max_cells``);
        False for a box that is not finite. Nothing changes."""
        if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)):
            return False
        left, down, right, up = self._growth(xmin, ymin, xmax, ymax)
        rows, cols = self.shape
        return (rows + down + up) * (cols + left + right) <= self.config.max_cells

    def ensure(self, xmin: float, ymin: float, xmax: float, ymax: float) -> bool:
        """Grow (by whole cells, in chunks) so the box is inside; True if it grew."""
        left, down, right, up = self._growth(xmin, ymin, xmax, ymax)
        if not (left or down or right or up):
            return False
        res = self.resolution
        rows, cols = self.shape
        new_rows, new_cols = rows + down + up, cols + left + right
        if new_rows * new_cols > self.config.max_cells:
            raise ValueError(
                f"grid would grow to {new_rows}x{new_cols} cells (> max_cells "
                f"{self.config.max_cells}): a pose or range far outside the map; "
                "raise max_cells or check the inputs"
            )
        grown = np.zeros((new_rows, new_cols), dtype=np.float32)
        grown[down : down + rows, left : left + cols] = self.logodds
        self.logodds = grown
        self.origin = (self.origin[0] - left * res, self.origin[1] - down * res)
        return True

    # -- updates ----------------------------------------------------------------------
    def add(self, flat_index: np.ndarray, delta_logodds: np.ndarray) -> int:
        """Add log-odds increments to cells (flat row-major indices; repeats summed), clamp.

        Each touched cell's increments are summed in float64 in their given order, added
        to the cell and clamped once. Returns the number of (index, delta) updates
        applied. O(k) in the k updates when their indices, or their box of rows and
        columns, span at most a few times k cells (a scan's cones), else O(k log k);
        never O(grid).
        """
        flat_index = np.asarray(flat_index, dtype=np.int64)
        n = int(flat_index.size)
        if n == 0:
            return 0
        delta = np.asarray(delta_logodds, dtype=np.float64)
        lo = int(flat_index.min())
        span = int(flat_index.max()) - lo + 1
        small = 4 * n + 65536
        if span <= small:
            rel = flat_index - lo
            total = np.bincount(rel, weights=delta, minlength=span)
            mark = np.zeros(span, dtype=bool)
            mark[rel] = True
            touched = mark.nonzero()[0]
            total = total[touched]
            touched += lo
        else:
            # The rows between span a wide map: index the cells' own box of columns.
            cols = self.logodds.shape[1]
            row = flat_index // cols
            col = flat_index - row * cols
            c0, r0 = int(col.min()), int(row.min())
            width = int(col.max()) - c0 + 1
            box = (int(row.max()) - r0 + 1) * width
            if box <= small:
                rel = (row - r0) * width + (col - c0)
                total = np.bincount(rel, weights=delta, minlength=box)
                mark = np.zeros(box, dtype=bool)
                mark[rel] = True
                local = mark.nonzero()[0]
                total = total[local]
                r, c = np.divmod(local, width)
                touched = (r + r0) * cols + (c + c0)
            else:
                touched, inv = np.unique(flat_index, return_inverse=True)
                total = np.bincount(inv, weights=delta)
        flat = self.logodds.reshape(-1)
        total += flat[touched]
        # np.clip, without its wrappers (the same values: lo < hi)
        np.maximum(total, self.config.l_min, out=total)
        np.minimum(total, self.config.l_max, out=total)
        flat[touched] = total
        self.updates += n
        return n

    # -- views ------------------------------------------------------------------------
    def probability(self) -> np.ndarray:
        """Occupancy probability of every cell, 1 / (1 + exp(-l))."""
        return 1.0 / (1.0 + np.exp(-self.logodds.astype(np.float64)))

    def trinary(self, occupied_thresh: float = 0.65, free_thresh: float = 0.196) -> np.ndarray:
        """int8 cells: 1 occupied (p > occupied_thresh), 0 free (p < free_thresh), -1 unknown."""
        p = self.probability()
        out = np.full(p.shape, -1, dtype=np.int8)
        out[p > occupied_thresh] = 1
        out[p < free_thresh] = 0
        return out

    def copy(self) -> OccupancyGrid:
        g = OccupancyGrid.__new__(OccupancyGrid)
        g.config = self.config
        g.resolution = self.resolution
        g.origin = self.origin
        g.logodds = self.logodds.copy()
        g.updates = self.updates
        return g

    @classmethod
    def from_array(
        cls,
        logodds: np.ndarray,
        resolution_m: float,
        origin_m: tuple[float, float],
        config: GridConfig | None = None,
    ) -> OccupancyGrid:
        """A grid holding ``logodds`` (rows along +y) at the given geometry."""
        arr = np.asarray(logodds, dtype=np.float32)
        if arr.ndim != 2 or arr.size == 0:
            raise ValueError("grid array must be 2-D and non-empty")
        base = config or GridConfig()
        cfg = GridConfig(
            resolution_m=resolution_m,
            origin_m=origin_m,
            size_m=(arr.shape[1] * resolution_m, arr.shape[0] * resolution_m),
            grow_chunk_m=base.grow_chunk_m,
            l_min=base.l_min,
            l_max=base.l_max,
            max_cells=base.max_cells,
        )
        g = cls(cfg)
        g.logodds = arr.copy()
        return g
