"""The IR inverse model's cells as first written: the specification of the fast path.

:meth:`mapping.ir_inverse.IrInverseModel.updates` computes exactly this (the same cells
in the same order, the same float64 increments) without sorting; the tests compare the
two on seeded random beams. Kept here, readable, as the definition of the lattice
(ir-grid-mapping fig. 4 and eq. 6; see :mod:`mapping.ir_inverse`):

- the cone of each beam (half-angle h, length ``reach``) is covered by a lattice of
  sample points with spacing 0.7 cells: along the beam t = (k + 1/2) s for k < ceil(reach
  / s), across it lat = j s for |j| <= ceil(reach tan h / s) + 1, kept where |lat| <= t
  tan h + res (a cone widened by one cell);
- each point falls in the cell floor((p - origin) / res); repeated (beam, cell) pairs
  count once, ordered by beam, then flat cell index;
- each cell's probability comes from its centre: distance r and angle alpha to the beam
  axis, less the angle the cell subtends (alpha_eff), free before the hit, occupied
  within w of it, untouched behind it (eq. 6 then attenuates towards 0.5).

Batches larger than ``model.max_samples_per_call`` lattice points are split (the grid is
grown for the whole batch first, so the flat indices of every part agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mapping.grid import OccupancyGrid
from mapping.ir_cone import attenuate, grow_for_cones
from numerics.angles import wrap

if TYPE_CHECKING:
    from mapping.ir_inverse import Beams, IrInverseModel


def reference_updates(
    model: IrInverseModel, grid: OccupancyGrid, beams: Beams
) -> tuple[np.ndarray, np.ndarray]:
    """(flat cell indices, log-odds increments) of all beams; grows ``grid`` to fit."""
    from mapping.ir_inverse import KIND_HIT, Beams

    if len(beams) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    res = grid.resolution
    h = model.half_angles(beams.sigma_rad)
    reach = model.reach(beams, res)
    grow_for_cones(grid, beams.x, beams.y, h, reach)
    spacing = 0.7 * res
    k_n = np.ceil(reach / spacing).astype(np.int64)
    j_n = np.ceil(reach * np.tan(h) / spacing).astype(np.int64) + 1
    per = k_n * (2 * j_n + 1)
    # Split large batches to bound memory.
    if per.sum() > model.max_samples_per_call and len(beams) > 1:
        idx_parts, dl_parts = [], []
        csum = np.cumsum(per)
        start = 0
        while start < len(beams):
            stop = int(np.searchsorted(csum, csum[start] - per[start] + model.max_samples_per_call))
            stop = max(stop, start + 1)
            sub = Beams(*(getattr(beams, n)[start:stop] for n in
                          ("x", "y", "angle", "range_m", "kind", "sigma_rad")))  # fmt: skip
            i, d = reference_updates(model, grid, sub)
            idx_parts.append(i)
            dl_parts.append(d)
            start = stop
        return np.concatenate(idx_parts), np.concatenate(dl_parts)
    total = int(per.sum())
    beam_id = np.repeat(np.arange(len(beams)), per)
    offsets = np.concatenate([[0], np.cumsum(per)[:-1]])
    q = np.arange(total) - offsets[beam_id]
    width = 2 * j_n[beam_id] + 1
    k = q // width
    j = q % width - j_n[beam_id]
    t = (k + 0.5) * spacing
    lat = j * spacing
    keep = np.abs(lat) <= t * np.tan(h[beam_id]) + res
    beam_id, t, lat = beam_id[keep], t[keep], lat[keep]
    ca, sa = np.cos(beams.angle), np.sin(beams.angle)
    px = beams.x[beam_id] + t * ca[beam_id] - lat * sa[beam_id]
    py = beams.y[beam_id] + t * sa[beam_id] + lat * ca[beam_id]
    row, col = grid.cell_of(px, py)
    rows, cols = grid.shape
    ncell = rows * cols
    key = np.unique(beam_id.astype(np.int64) * ncell + row * cols + col)
    b = key // ncell
    flat = key % ncell
    row, col = flat // cols, flat % cols
    cx, cy = grid.centre_of(row, col)
    vx, vy = cx - beams.x[b], cy - beams.y[b]
    r = np.hypot(vx, vy)
    alpha = np.abs(wrap(np.arctan2(vy, vx) - beams.angle[b]))
    cell_radius = 0.7072 * res
    alpha_eff = np.maximum(
        0.0, alpha - np.arcsin(np.minimum(1.0, cell_radius / np.maximum(r, 1e-9)))
    )
    alpha_eff = np.where(r <= cell_radius, 0.0, alpha_eff)
    hb = h[b]
    c = model.config
    w = max(c.hit_halfwidth_m, 0.75 * res)
    z = beams.range_m[b]
    hit = beams.kind[b] == KIND_HIT
    p = np.full(r.shape, 0.5)
    with np.errstate(invalid="ignore"):
        p = np.where(hit & (r < z - w), c.p_free, p)
        p = np.where(hit & (np.abs(r - z) <= w), c.p_occupied, p)
    p = np.where(~hit & (r <= c.max_range_m), c.p_free, p)
    sel = (alpha_eff <= hb) & (p != 0.5)
    p = attenuate(p[sel], alpha_eff[sel], hb[sel])
    dl = np.log(p) - np.log1p(-p)
    return flat[sel], dl
