"""Map scores that rank maps as a person would, against a reference map.

The paper's grid match ratio (ir-grid-mapping §4; :mod:`mapping.quality`) counts the
cells known in both maps that agree. Free cells are most of any map and each map is
compared on its own set of known cells, so a map smeared by drift still scores 0.9 and
can outrank a better one. Here every map is scored on the **same** cells:

- the reference (:class:`ReferenceMap`): walls, free space and unknown on a lattice, and
  the cells the sensors could observe from the reference poses (``observed``: the cells
  the IR map built at the reference poses knows; all known cells when not given);
- **occupied precision**: the built map's occupied cells (all of them, also outside the
  reference) lying within ``tolerance_cells`` of a reference wall;
- **occupied recall**: the observed reference walls with a built occupied cell within
  ``tolerance_cells``; the denominator is the same for every map;
- **alignment**: over the observed known reference cells, the mean of the fraction of
  walls found (the recall) and the fraction of free cells the built map calls free
  (balanced, so free space does not drown the walls); a map shifted or rotated off the
  reference loses on both;
- the paper's match ratio on the same lattice, for comparison only.

The built grid is resampled onto the reference lattice by nearest cell centre (no
rotation or shift is fitted: a map in the wrong place is a wrong map).
:func:`laser_map` builds a reference from laser scans at reference poses (log-odds,
hits and free passes), for real data sets.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.ndimage import binary_dilation

from mapping.grid import OccupancyGrid, logit


@dataclass(frozen=True)
class ReferenceMap:
    """Reference cells (int8: 1 wall, 0 free, -1 unknown; rows along +y) on a lattice,
    and the cells the sensors could observe (bool, same shape; None = all known)."""

    cells: np.ndarray
    resolution: float
    origin: tuple[float, float]
    observed: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.cells.ndim != 2:
            raise ValueError("reference map cells must be 2-D")
        if self.observed is not None and self.observed.shape != self.cells.shape:
            raise ValueError("reference map: observed mask and cells differ in shape")

    def with_observed(self, grid: OccupancyGrid) -> ReferenceMap:
        """This reference, observed where ``grid`` (the map at the reference poses) knows."""
        seen = resample(grid.trinary(), grid, self) >= 0
        return ReferenceMap(self.cells, self.resolution, self.origin, seen)


@dataclass(frozen=True)
class MapScore:
    occupied_precision: float
    occupied_recall: float
    alignment: float
    free_agreement: float
    match_ratio: float
    built_occupied: int
    reference_walls: int
    reference_free: int
    tolerance_cells: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def resample(cells: np.ndarray, grid: OccupancyGrid, ref: ReferenceMap) -> np.ndarray:
    """``cells`` (on ``grid``'s lattice) at the reference's cell centres (-1 outside)."""
    rows, cols = ref.cells.shape
    cx = ref.origin[0] + (np.arange(cols) + 0.5) * ref.resolution
    cy = ref.origin[1] + (np.arange(rows) + 0.5) * ref.resolution
    gr = np.floor((cy - grid.origin[1]) / grid.resolution).astype(np.int64)
    gc = np.floor((cx - grid.origin[0]) / grid.resolution).astype(np.int64)
    gr_ok = (gr >= 0) & (gr < cells.shape[0])
    gc_ok = (gc >= 0) & (gc < cells.shape[1])
    out = np.full((rows, cols), -1, dtype=np.int8)
    sub = cells[np.ix_(gr[gr_ok], gc[gc_ok])]
    out[np.ix_(gr_ok, gc_ok)] = sub
    return out


def score(
    grid: OccupancyGrid,
    ref: ReferenceMap,
    tolerance_cells: int = 2,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
) -> MapScore:
    """The scores of ``grid`` against ``ref`` (module doc)."""
    if tolerance_cells < 0:
        raise ValueError("tolerance_cells must be >= 0")
    tri = grid.trinary(occupied_thresh, free_thresh)
    built = resample(tri, grid, ref)
    n_built = int((tri == 1).sum())
    scale = grid.resolution / ref.resolution
    n_built_ref = int(round(n_built * scale * scale))
    walls = ref.cells == 1
    free = ref.cells == 0
    obs = ref.observed if ref.observed is not None else ref.cells >= 0
    b_occ = built == 1
    if tolerance_cells > 0:
        st = np.ones((2 * tolerance_cells + 1,) * 2, dtype=bool)
        walls_near = binary_dilation(walls, structure=st)
        occ_near = binary_dilation(b_occ, structure=st)
    else:
        walls_near, occ_near = walls, b_occ
    w_obs = walls & obs
    f_obs = free & obs
    n_w, n_f = int(w_obs.sum()), int(f_obs.sum())
    precision = int((b_occ & walls_near).sum()) / n_built_ref if n_built_ref else 0.0
    recall = int((w_obs & occ_near).sum()) / n_w if n_w else 0.0
    free_ok = int((f_obs & (built == 0)).sum()) / n_f if n_f else 0.0
    known = (built >= 0) & (ref.cells >= 0)
    n_known = int(known.sum())
    match = int((known & (built == ref.cells)).sum()) / n_known if n_known else 0.0
    return MapScore(
        occupied_precision=min(1.0, precision),
        occupied_recall=recall,
        alignment=0.5 * (recall + free_ok),
        free_agreement=free_ok,
        match_ratio=match,
        built_occupied=n_built,
        reference_walls=n_w,
        reference_free=n_f,
        tolerance_cells=tolerance_cells,
    )


def laser_map(
    poses: np.ndarray,
    ranges: np.ndarray,
    angles: np.ndarray,
    max_range_m: float,
    resolution_m: float,
    lattice_origin: tuple[float, float] = (0.0, 0.0),
    laser_on_robot: tuple[float, float, float] = (0.0, 0.0, 0.0),
    reach_m: float = 8.0,
    p_hit: float = 0.75,
    p_pass: float = 0.4,
    chunk: int = 8,
) -> ReferenceMap:
    """A reference map from laser scans ``ranges`` (N, B) at bearings ``angles`` taken at
    robot ``poses`` (N, 3; rows with NaN skipped): every cell a beam ends in gains
    logit(p_hit), every cell it passes gains logit(p_pass) (up to ``reach_m``; a reading
    >= ``max_range_m`` passes its whole reach), clamped to +-4; wall where p > 0.65, free
    where p < 0.196. The lattice is ``lattice_origin`` + whole cells."""
    poses = np.asarray(poses, dtype=float)
    ok = np.all(np.isfinite(poses), axis=1)
    poses, ranges = poses[ok], np.asarray(ranges, dtype=float)[ok]
    if len(poses) == 0:
        raise ValueError("laser_map: no scan with a reference pose")
    res = float(resolution_m)
    lx, ly, lyaw = laser_on_robot
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    ox = poses[:, 0] + c * lx - s * ly
    oy = poses[:, 1] + s * lx + c * ly
    pad = reach_m + 2 * res
    x0 = lattice_origin[0] + res * math.floor((ox.min() - pad - lattice_origin[0]) / res)
    y0 = lattice_origin[1] + res * math.floor((oy.min() - pad - lattice_origin[1]) / res)
    cols = int(math.ceil((ox.max() + pad - x0) / res))
    rows = int(math.ceil((oy.max() + pad - y0) / res))
    hits = np.zeros(rows * cols, dtype=np.float64)
    passes = np.zeros(rows * cols, dtype=np.float64)
    t = np.arange(0.5 * res, reach_m, 0.8 * res)
    ncell = rows * cols
    for a in range(0, len(poses), chunk):
        r = ranges[a : a + chunk]
        valid = r > 0
        ret = valid & (r < max_range_m) & (r <= reach_m)
        end = np.where(ret, r, np.where(valid, reach_m, 0.0))
        ang = poses[a : a + chunk, 2:3] + lyaw + angles[None, :]
        ca, sa = np.cos(ang), np.sin(ang)
        bx, by = ox[a : a + chunk, None], oy[a : a + chunk, None]
        # passes: the samples before the end cell (a cell sampled twice counts twice)
        k = np.minimum(np.searchsorted(t, end - res), len(t))
        mask = np.arange(len(t)) < k[..., None]
        tt = np.broadcast_to(t, mask.shape)[mask]
        cb = np.broadcast_to(ca[..., None], mask.shape)[mask]
        sb = np.broadcast_to(sa[..., None], mask.shape)[mask]
        xb = np.broadcast_to(bx[..., None], mask.shape)[mask]
        yb = np.broadcast_to(by[..., None], mask.shape)[mask]
        col = ((xb + cb * tt - x0) / res).astype(np.int64)
        row = ((yb + sb * tt - y0) / res).astype(np.int64)
        passes += np.bincount(row * cols + col, minlength=ncell)
        hx, hy = (bx + ca * end)[ret], (by + sa * end)[ret]
        hcell = ((hy - y0) / res).astype(np.int64) * cols + ((hx - x0) / res).astype(np.int64)
        hits += np.bincount(hcell, minlength=ncell)
    lo = np.clip(hits * logit(p_hit) + passes * logit(p_pass), -4.0, 4.0).reshape(rows, cols)
    p = 1.0 / (1.0 + np.exp(-lo))
    cells = np.full((rows, cols), -1, dtype=np.int8)
    cells[p > 0.65] = 1
    cells[p < 0.196] = 0
    return ReferenceMap(cells, res, (x0, y0))
