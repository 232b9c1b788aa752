"""The cells of IR beam cones and their log-odds increments, without sorting.

Computes exactly what :func:`mapping.ir_reference.reference_updates` defines (the same
cells in the same order, the same float64 increments; ir-grid-mapping fig. 4 and eq. 6),
at a fraction of its cost:

- the lattice rows of each cone (fixed t = (k + 1/2) s) are cut to the columns the
  reference keeps (|j s| <= t tan h + res, decided with the same float products), so no
  point outside the cone is made;
- each point's cell is computed with the reference's operations in the reference's
  order (so the same float rounding), as an index into a bitmap per beam that covers the
  beam's cone (its bounding box, found from the ends of the lattice rows);
- marking the bitmap removes the repeated (beam, cell) pairs, and reading it back in
  order gives the cells by beam, then by flat index: the order ``np.unique`` gave;
- each cell's distance and angle to the beam are computed once; the cells that change
  (free before the hit, occupied at it, inside the eq. 6 cone) are picked in one pass,
  and eq. 6's power and the log-odds are computed for those only. The wrap of the angle
  is ``numerics.angles.wrap_angles``' ``np.mod`` done as the one add or subtract it
  amounts to for beams whose angles lie in (-2 pi, 2 pi), and as fmod's exact remainder
  from a split 2 pi for the others (the association's headings are not wrapped: after
  loops they reach tens of radians), both exact (:func:`_wrap_abs`).

Every step is a whole-array numpy operation over all beams of a call, so a scan of six
beams costs a few dozen numpy calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from numerics.angles import TWO_PI

if TYPE_CHECKING:
    from mapping.grid import OccupancyGrid
    from mapping.ir_inverse import InverseModelConfig


def attenuate(p: np.ndarray, alpha: np.ndarray, three_sigma: np.ndarray) -> np.ndarray:
    """Eq. (6): pull p towards 0.5 with the exponent 1 + |alpha / (3 sigma)|."""
    p = np.asarray(p, dtype=float)
    e = 1.0 + np.abs(np.asarray(alpha, dtype=float) / np.asarray(three_sigma, dtype=float))
    d = np.abs(p - 0.5) ** e
    return np.where(p < 0.5, 0.5 - d, np.where(p > 0.5, 0.5 + d, p))


def cone_extent(reach: Any, h: Any, res: float) -> Any:
    """How far from its sensor a cone may update cells: its far corners, reach / cos(h)
    away, and two cells."""
    return reach / np.cos(h) + 2 * res


def grow_for_cones(
    grid: OccupancyGrid, x: np.ndarray, y: np.ndarray, h: np.ndarray, reach: np.ndarray
) -> None:
    """Grow the grid to hold every cone (:func:`cone_extent`)."""
    ext = cone_extent(reach, h, grid.resolution)
    grid.ensure(
        float((x - ext).min()),
        float((y - ext).min()),
        float((x + ext).max()),
        float((y + ext).max()),
    )


def _runs(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner of each element, first element of each run) of runs of ``counts`` elements."""
    starts = counts.cumsum() - counts
    return np.arange(len(counts)).repeat(counts), starts


def _lattice_rows(
    reach: np.ndarray, tan_h: np.ndarray, res: float, spacing: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The lattice rows of every beam: (beam of each row, t, highest |j| kept, rows per
    beam). Row k of a beam keeps j in [-J, J], J the largest j <= j_n with j s <= t tan h
    + res (the reference's test, with its float products)."""
    k_n = np.ceil(reach / spacing).astype(np.int64)
    j_n = np.ceil(reach * tan_h / spacing).astype(np.int64) + 1
    kb, starts = _runs(k_n)
    k = np.arange(len(kb)) - starts[kb]
    t = (k + 0.5) * spacing
    lim = t * tan_h[kb] + res
    big = np.floor(lim / spacing).astype(np.int64)  # within one of the exact answer
    big += (big + 1) * spacing <= lim
    big -= big * spacing > lim
    return kb, t, np.minimum(big, j_n[kb]), k_n


@dataclass(frozen=True)
class Lattice:
    """The lattice points of a batch of cones as far as they depend on the cones' lengths
    and half-angles alone, not on where the cones lie: the rows (beam, t, highest |j|,
    each beam's first row), the points per row and each point's offset
    j s along its row. The same scans at other poses (the drift hypotheses' maps) share
    it."""

    kb: np.ndarray
    t: np.ndarray
    big: np.ndarray
    first: np.ndarray
    cnt: np.ndarray
    lat: np.ndarray


def lattice(reach: np.ndarray, h: np.ndarray, res: float) -> Lattice:
    """The :class:`Lattice` of cones of lengths ``reach`` and half-angles ``h``."""
    spacing = 0.7 * res
    kb, t, big, k_n = _lattice_rows(reach, np.tan(h), res, spacing)
    first = k_n.cumsum() - k_n
    cnt = 2 * big + 1
    lat = np.arange(int(cnt.sum()), dtype=np.int64)
    lat -= (cnt.cumsum() - cnt + big).repeat(cnt)
    return Lattice(kb, t, big, first, cnt, lat * spacing)


def cone_cells(
    grid: OccupancyGrid,
    x: np.ndarray,
    y: np.ndarray,
    angle: np.ndarray,
    h: np.ndarray,
    reach: np.ndarray,
    lat: Lattice | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cells a lattice point of a beam's cone falls in, each (beam, cell) once,
    ordered by beam then row then column. The grid must hold them. ``lat``: the cones'
    :func:`lattice` if it is known. Returns the cells per beam, and the cells' row and
    column (as floats) and flat index."""
    res = grid.resolution
    ox, oy = grid.origin
    spacing = 0.7 * res
    ca, sa = np.cos(angle), np.sin(angle)
    if lat is None:
        lat = lattice(reach, h, res)
    kb, t, big, first, cnt = lat.kb, lat.t, lat.big, lat.first, lat.cnt
    # The start of each row (world), and its two end points' cells: the beam's box.
    sa_k, ca_k = sa[kb], ca[kb]
    ax = x[kb] + t * ca_k
    ay = y[kb] + t * sa_k
    half = big * spacing
    ends_c = [np.floor((ax + s * half * sa_k - ox) / res) for s in (-1.0, 1.0)]
    ends_r = [np.floor((ay + s * half * ca_k - oy) / res) for s in (-1.0, 1.0)]
    c0 = np.minimum.reduceat(np.minimum(*ends_c), first) - 1.0
    c1 = np.maximum.reduceat(np.maximum(*ends_c), first) + 1.0
    r0 = np.minimum.reduceat(np.minimum(*ends_r), first) - 1.0
    r1 = np.maximum.reduceat(np.maximum(*ends_r), first) + 1.0
    width = float(np.max(c1 - c0)) + 1.0
    area = (r1 - r0 + 1.0) * width
    off = np.cumsum(area) - area
    # Every lattice point (row k of a beam, column j), with the reference's arithmetic,
    # as the index row * width + col + base into the beams' bitmaps (exact in float64).
    tmp = sa_k.repeat(cnt)
    tmp *= lat.lat
    px = ax.repeat(cnt)
    px -= tmp
    px -= ox
    px /= res
    np.floor(px, out=px)
    np.multiply(ca_k.repeat(cnt), lat.lat, out=tmp)
    py = ay.repeat(cnt)
    py += tmp
    py -= oy
    py /= res
    np.floor(py, out=py)
    py *= width
    py += px
    py += (off - r0 * width - c0)[kb].repeat(cnt)
    mark = np.zeros(int(off[-1] + area[-1]), dtype=bool)
    mark[py.astype(np.intp)] = True
    idx = mark.nonzero()[0]
    ends = idx.searchsorted(np.append(off, mark.size))
    per = ends[1:] - ends[:-1]
    local = idx - off.repeat(per)
    lr = np.floor(local / width)  # exact: integers far below 2**52
    row = lr + r0.repeat(per)
    col = local - lr * width + c0.repeat(per)
    return per, row, col, (row * grid.shape[1] + col).astype(np.int64)


# 2 pi in two parts, the first of 24 bits: q * _TWO_PI_HI and q * _TWO_PI_LO are exact
# for integers |q| <= 2**20 (24 + 20 and 29 + 20 bits).
_TWO_PI_HI = math.ldexp(math.floor(math.ldexp(TWO_PI, 21)), -21)
_TWO_PI_LO = TWO_PI - _TWO_PI_HI  # exact (Sterbenz)
_Q_MAX = 2.0**20
_FINITE_RAD = 2.0**18  # beams' |angle| below it (rad): alpha + pi far below 2**20 turns


def _mod_two_pi(a: np.ndarray, finite: bool = False) -> np.ndarray:
    """np.mod(a, 2 pi), exactly, at a fraction of fmod's cost: fmod(a, m) is a - q m with
    q = trunc(a / m), always representable; a - q m_hi is exact (both multiples of the
    ulp of m's last bit, the difference below 8) and so is the one rounding of (a - q
    m_hi) - q m_lo; the quotient can only be one too far from 0 (the division rounded up
    to an integer), which leaves the remainder of the wrong sign, and one exact step
    corrects it. Then numpy's rule: a negative remainder gets m added. ``finite``: every
    value is finite and below 2**20 turns (the caller knows), so none is numpy's own."""
    q = np.trunc(a / TWO_PI)
    r = a - q * _TWO_PI_HI
    r -= q * _TWO_PI_LO
    off = (((r < 0.0) & (a > 0.0)) | ((r > 0.0) & (a < 0.0))).nonzero()[0]
    if len(off):
        r[off] -= np.copysign(TWO_PI, r[off])
    np.add(r, TWO_PI, out=r, where=r < 0.0)
    if finite:
        return r
    huge = (~(np.abs(q) <= _Q_MAX)).nonzero()[0]  # and NaN: numpy's own
    if len(huge):
        r[huge] = np.mod(a[huge], TWO_PI)
    return r


def _wrap_abs(a: np.ndarray, near: bool = False, finite: bool = False) -> np.ndarray:
    """|wrap_angles(a)|, exactly: np.mod(a + pi, 2 pi) (numpy's fmod-based remainder)
    minus pi. ``near``: every a + pi lies in [-2 pi, 4 pi) (the beams' angles lie in
    (-2 pi, 2 pi)), where the remainder is one add or subtract; else
    :func:`_mod_two_pi` (``finite``: its values finite, below 2**20 turns). (Its -pi is
    pi's wrap; the absolute value makes them one.)"""
    a = a + math.pi
    if near:
        m = np.where(a < 0.0, a + TWO_PI, a)
        np.subtract(m, TWO_PI, out=m, where=a >= TWO_PI)
    else:
        m = _mod_two_pi(a, finite)
    m -= math.pi
    return np.abs(m, out=m)


def cell_updates(
    grid: OccupancyGrid,
    config: InverseModelConfig,
    beams_xy: tuple[np.ndarray, np.ndarray],
    angle: np.ndarray,
    hit: np.ndarray,
    z: np.ndarray,
    h: np.ndarray,
    cells: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cells of each beam, flat index, log-odds increment) of the cells that change:
    fig. 4 on each cell centre's distance, eq. 6 on its angle to the axis. ``cells``:
    from :func:`cone_cells`. ``hit``: the beams that returned a range ``z`` (NaN for the
    others: they clear up to the maximum range)."""
    per, row, col, flat = cells
    res = grid.resolution
    ox, oy = grid.origin
    x, y = beams_xy
    col += 0.5
    col *= res
    vx = np.add(ox, col, out=col)
    vx -= x.repeat(per)
    row += 0.5
    row *= res
    vy = np.add(oy, row, out=row)
    vy -= y.repeat(per)
    r = np.hypot(vx, vy)
    w = max(config.hit_halfwidth_m, 0.75 * res)
    # free: r < z - w before a hit, r <= max range for a beam that saw nothing.
    lim = np.where(hit, z - w, math.nextafter(config.max_range_m, math.inf))
    free = r < lim.repeat(per)
    with np.errstate(invalid="ignore"):
        tmp = r - z.repeat(per)
        occ = np.abs(tmp, out=tmp) <= w
    free |= occ
    # Eq. 6's angle: from the axis to the nearest point of the cell.
    alpha = np.arctan2(vy, vx, out=vy)
    alpha -= angle.repeat(per)
    # The beams' angles within (-2 pi, 2 pi) put alpha + pi within [-2 pi, 4 pi); far
    # below 2**20 turns (and finite: the cells' arctan2 is) no value is np.mod's own.
    most = float(np.abs(angle).max())
    alpha = _wrap_abs(alpha, most < TWO_PI - 1e-6, most < _FINITE_RAD)
    cell_radius = 0.7072 * res
    # arcsin(min(cell_radius / max(r, 1e-9), 1)): the two clamps change only cells with
    # r <= cell_radius (a quotient of at least 1), whose alpha is set to 0 below.
    with np.errstate(divide="ignore", invalid="ignore"):
        tmp = np.divide(cell_radius, r, out=vx)
        alpha -= np.arcsin(tmp, out=tmp)
    np.maximum(alpha, 0.0, out=alpha)
    alpha[r <= cell_radius] = 0.0
    hb = h.repeat(per)
    free &= alpha <= hb
    sel = free.nonzero()[0]
    # Eq. 6 as attenuate() computes it: |p - 0.5| ** (1 + |alpha / 3 sigma|) (alpha >= 0).
    occ = occ[sel]
    e = alpha[sel]
    e /= hb[sel]
    e += 1.0
    free_d, occ_d = abs(config.p_free - 0.5), abs(config.p_occupied - 0.5)
    d = np.power(np.where(occ, occ_d, free_d), e, out=e)
    p = np.subtract(0.5, d, out=d, where=~occ)
    np.add(0.5, d, out=p, where=occ)
    dl = np.log(p)
    dl -= np.log1p(np.negative(p, out=p), out=p)
    ends = sel.searchsorted(per.cumsum())
    ends[1:] -= ends[:-1].copy()
    return ends, flat[sel], dl
