"""Inverse sensor model of the Sharp IR beams, widened by heading uncertainty.

ir-grid-mapping.txt fig. 4: along a beam that returned a range z, cells nearer than the
hit are probably free (p_free), cells at the hit (|r - z| <= w) probably occupied
(p_occupied) and cells behind it are not touched (unknown, p = 0.5). A reading that saw
nothing (status too_far or no_return) only clears the cells up to the maximum range.
Readings flagged too_near or invalid carry no usable range and are skipped (counted).

Eq. (6): the robot's heading is uncertain (sigma from the heading Kalman filter, eq.
1-4), so the beam may point anywhere within +-3 sigma. Every cell j inside that cone is
updated with its probability pulled towards 0.5:

    p_j = 0.5 - (0.5 - p)^(1 + |alpha / 3 sigma|)   if p < 0.5
    p_j = 0.5 + (p - 0.5)^(1 + |alpha / 3 sigma|)   if p > 0.5

where alpha is the angle between the beam axis and the direction to the cell. Two
choices the paper leaves open: the cone is never narrower than the sensor's own beam
(``min_half_angle_rad``; with sigma -> 0 eq. 6 would update a line of zero width), and
alpha is measured to the nearest point of the cell (a cell the axis passes through has
alpha = 0), so that the cells on the axis get the full update at any range.

Everything is vectorised over all beams of a call (one scan, or many scans when data
is re-inserted): the cone of each beam is covered by a lattice of sample points with
spacing 0.7 cells (any cell lying inside the cone receives one), the points are binned
into cells, repeated (beam, cell) pairs are reduced to one, and each cell's update is
computed from its exact centre geometry. :mod:`mapping.ir_reference` writes this lattice
down plainly; :mod:`mapping.ir_cone` computes the same cells and increments, bit for
bit, without sorting; :mod:`mapping.ir_memo` keeps them for a second grid when asked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.grid import OccupancyGrid
from mapping.ir_cone import (
    attenuate,
    cell_updates,
    cone_cells,
    cone_extent,
    grow_for_cones,
    lattice,
)
from mapping.ir_memo import UpdateMemo
from mapping.se2 import compose
from msgs import IrScan, Pose2D

__all__ = ["attenuate"]  # eq. 6 lives with the cone cells (mapping.ir_cone)

KIND_SKIP = -1
KIND_HIT = 0
KIND_CLEAR = 1
_STATUS_KIND = {"ok": KIND_HIT, "too_far": KIND_CLEAR, "no_return": KIND_CLEAR}
_FIELDS = ("x", "y", "angle", "range_m", "kind", "sigma_rad")
_MEMO_MODES = ("use", "keep", "take", "off")


@dataclass(frozen=True)
class InverseModelConfig:
    """Parameters of the IR inverse sensor model (fig. 4) and its eq. 6 cone.

    p_free / p_occupied: the model's probabilities before attenuation.
    hit_halfwidth_m: half thickness of the occupied band about the measured range (at
        least 0.75 cell is used).
    max_range_m: the sensor's maximum valid range (Sharp GP2Y0A710K0F: 5.5 m).
    sigma_multiple: the cone is +- sigma_multiple * sigma (the paper's 3 sigma).
    min_half_angle_rad: the sensor's own beam half-angle (cone floor).
    max_half_angle_rad: cone ceiling, so a lost heading does not paint half the map.
    use_heading_uncertainty: False gives the plain fig. 4 model (cone = own beam).
    """

    p_free: float = 0.35
    p_occupied: float = 0.75
    hit_halfwidth_m: float = 0.075
    max_range_m: float = 5.5
    sigma_multiple: float = 3.0
    min_half_angle_rad: float = math.radians(1.0)
    max_half_angle_rad: float = math.radians(20.0)
    use_heading_uncertainty: bool = True

    def __post_init__(self) -> None:
        if not 0.0 < self.p_free < 0.5:
            raise ValueError(f"inverse model p_free must be in (0, 0.5), got {self.p_free}")
        if not 0.5 < self.p_occupied < 1.0:
            raise ValueError(f"inverse model p_occupied must be in (0.5, 1), got {self.p_occupied}")
        if self.max_range_m <= 0 or self.hit_halfwidth_m < 0:
            raise ValueError("inverse model max_range_m must be > 0, hit_halfwidth_m >= 0")
        if not 0 < self.min_half_angle_rad <= self.max_half_angle_rad < math.pi / 2:
            raise ValueError(
                "inverse model needs 0 < min_half_angle_rad <= max_half_angle_rad < pi/2"
            )


@dataclass
class Beams:
    """Beams in the world frame: origin (x, y), direction, range, kind, heading sigma."""

    x: np.ndarray
    y: np.ndarray
    angle: np.ndarray
    range_m: np.ndarray
    kind: np.ndarray
    sigma_rad: np.ndarray
    skipped: int = 0

    def __len__(self) -> int:
        return int(self.x.shape[0])

    @staticmethod
    def concat(parts: list[Beams]) -> Beams:
        if not parts:
            z = np.zeros(0)
            return Beams(z, z, z, z, np.zeros(0, dtype=np.int8), z)
        return Beams(
            *(
                np.concatenate([getattr(b, n) for b in parts])
                for n in ("x", "y", "angle", "range_m", "kind", "sigma_rad")
            ),  # fmt: skip
            skipped=sum(b.skipped for b in parts),
        )


def scan_kinds(scan: IrScan) -> tuple[np.ndarray, np.ndarray]:
    """(ranges, kinds) of an IrScan: ok -> hit, too_far/no_return -> clear, else skip."""
    n = len(scan.status)
    if len(scan.ranges_m) != n:
        raise ValueError(
            f"IrScan has {len(scan.ranges_m)} ranges but {n} status flags (board {scan.board_id})"
        )
    kinds = np.array([_STATUS_KIND.get(s, KIND_SKIP) for s in scan.status], dtype=np.int8)
    ranges = np.asarray(scan.ranges_m, dtype=float)
    bad = (kinds == KIND_HIT) & ~(np.isfinite(ranges) & (ranges > 0))
    kinds[bad] = KIND_SKIP
    return ranges, kinds


def beams_from_scan(pose: Pose2D, sigma_rad: float, scan: IrScan, mounts: np.ndarray) -> Beams:
    """World-frame beams of one scan taken at ``pose``; mounts (K, 3) = x, y, yaw on the robot."""
    mounts = np.atleast_2d(np.asarray(mounts, dtype=float))
    ranges, kinds = scan_kinds(scan)
    if mounts.shape != (len(kinds), 3):
        raise ValueError(
            f"IR mounts have shape {mounts.shape} but the scan has {len(kinds)} channels: "
            "give one (x, y, yaw) mount per channel in the robot's ir mounts config"
        )
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    x = pose.x + c * mounts[:, 0] - s * mounts[:, 1]
    y = pose.y + s * mounts[:, 0] + c * mounts[:, 1]
    keep = kinds != KIND_SKIP
    sig = float(sigma_rad) if math.isfinite(sigma_rad) and sigma_rad >= 0 else 0.0
    return Beams(
        x[keep],
        y[keep],
        (pose.theta + mounts[:, 2])[keep],
        np.where(kinds == KIND_HIT, ranges, np.nan)[keep],
        kinds[keep],
        np.full(int(keep.sum()), sig),
        skipped=int((~keep).sum()),
    )


@dataclass
class IrInverseModel:
    """Computes the cells and log-odds increments of a batch of beams (fig. 4 + eq. 6)."""

    config: InverseModelConfig = field(default_factory=InverseModelConfig)
    max_samples_per_call: int = 400_000
    reuse_cells: int = 0

    def __post_init__(self) -> None:
        # reuse_cells > 0: keep up to that many cell updates of the beams inserted, to
        # insert the same beams into another grid of the same origin without computing
        # them again (data association's reference map; mapping.ir_memo).
        self._memo = UpdateMemo(self.reuse_cells) if self.reuse_cells > 0 else None

    def half_angles(self, sigma_rad: np.ndarray) -> np.ndarray:
        c = self.config
        if not c.use_heading_uncertainty:
            return np.full(np.shape(sigma_rad), c.min_half_angle_rad)
        h = np.maximum(c.sigma_multiple * np.asarray(sigma_rad, dtype=float), c.min_half_angle_rad)
        return np.minimum(h, c.max_half_angle_rad, out=h)  # np.clip, without its wrappers

    def scan_box(
        self, pose: np.ndarray, mounts: np.ndarray, res: float, margin_m: float = 0.0
    ) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) that the grid (cell ``res``) grows to hold for any scan
        taken at ``pose`` (x, y, theta) from sensors at ``mounts`` (K, 3): the widest cone
        of :meth:`reach` and the largest half-angle (:func:`mapping.ir_cone.cone_extent`),
        widened by ``margin_m``."""
        sens = compose(np.broadcast_to(np.asarray(pose, dtype=float), mounts.shape), mounts)
        x, y = sens[:, 0], sens[:, 1]
        cfg = self.config
        reach = cfg.max_range_m + max(cfg.hit_halfwidth_m, 0.75 * res)
        r = float(cone_extent(reach, cfg.max_half_angle_rad, res)) + margin_m
        return (float(x.min()) - r, float(y.min()) - r, float(x.max()) + r, float(y.max()) + r)

    def reach(self, beams: Beams, res: float) -> np.ndarray:
        """Length of each beam's cone: past the hit by the occupied band's half width,
        the maximum range for a beam that saw nothing (a NaN hit: the band only)."""
        c = self.config
        w = max(c.hit_halfwidth_m, 0.75 * res)
        z = beams.range_m
        r = np.where((beams.kind == KIND_HIT) & ~np.isnan(z), z, 0.0)
        r += w
        np.copyto(r, c.max_range_m, where=beams.kind != KIND_HIT)
        return np.minimum(r, c.max_range_m + w, out=r)

    def _parts(self, beams: Beams, res: float) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """(half-angles, reaches, the ends of the parts of at most
        ``max_samples_per_call`` lattice points, bounded as the rectangle k_n (2 j_n + 1))."""
        h, reach, csum = self._bound(beams, res)
        if csum[-1] <= self.max_samples_per_call:
            return h, reach, [len(beams)]
        ends, start = [], 0
        while start < len(beams):
            limit = (csum[start - 1] if start else 0.0) + self.max_samples_per_call
            start = max(int(np.searchsorted(csum, limit, side="right")), start + 1)
            ends.append(start)
        return h, reach, ends

    def _bound(self, beams: Beams, res: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(half-angles, reaches, cumulative bound on the beams' lattice points)."""
        h = self.half_angles(beams.sigma_rad)
        reach = self.reach(beams, res)
        spacing = 0.7 * res
        per = np.ceil(reach / spacing) * (2 * (np.ceil(reach * np.tan(h) / spacing) + 1) + 1)
        return h, reach, per.cumsum()

    def _cone_updates(
        self,
        grid: OccupancyGrid,
        beams: Beams,
        h: np.ndarray,
        reach: np.ndarray,
        memo: str = "use",
    ) -> tuple[np.ndarray, np.ndarray]:
        """Grow the grid to hold the beams' cones, then their cells and increments."""
        grow_for_cones(grid, beams.x, beams.y, h, reach)
        use = reach > 0  # a cone of no length has no lattice point
        if not use.all():
            keep = np.flatnonzero(use)
            if len(keep) == 0:
                return np.zeros(0, dtype=np.int64), np.zeros(0)
            beams = Beams(*(getattr(beams, n)[keep] for n in _FIELDS))
            h, reach = h[keep], reach[keep]
        x, y, angle = (
            np.ascontiguousarray(a, dtype=float) for a in (beams.x, beams.y, beams.angle)
        )
        hit = beams.kind == KIND_HIT
        z = np.where(hit, beams.range_m, np.nan)

        def compute(i: np.ndarray | slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            cells = cone_cells(grid, x[i], y[i], angle[i], h[i], reach[i])
            return cell_updates(
                grid, self.config, (x[i], y[i]), angle[i], hit[i], z[i], h[i], cells
            )

        if self._memo is None or memo == "off":
            return compute(slice(None))[1:]
        rows = np.column_stack([x, y, angle, beams.range_m, beams.kind, beams.sigma_rad])
        return self._memo.updates(grid, rows, compute, memo != "take", memo != "keep")

    def updates(self, grid: OccupancyGrid, beams: Beams) -> tuple[np.ndarray, np.ndarray]:
        """(flat cell indices, log-odds increments) of all beams; grows ``grid`` to fit.

        The cells by beam, then by flat index (a cell once per beam). Exactly
        :func:`mapping.ir_reference.reference_updates`, computed by :mod:`mapping.ir_cone`
        a bounded part at a time.
        """
        if len(beams) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        h, reach, ends = self._parts(beams, grid.resolution)
        if len(ends) == 1:
            return self._cone_updates(grid, beams, h, reach)
        grow_for_cones(grid, beams.x, beams.y, h, reach)  # the whole batch first
        parts, start = [], 0
        for stop in ends:
            sub = Beams(*(getattr(beams, n)[start:stop] for n in _FIELDS))
            parts.append(self._cone_updates(grid, sub, h[start:stop], reach[start:stop]))
            start = stop
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def integrate(self, grid: OccupancyGrid, beams: Beams, memo: str = "use") -> int:
        """Apply the beams to the grid, a bounded part at a time (each part's updates
        applied before the next is computed, so memory stays bounded); returns the number
        of cell updates. ``memo`` (with ``reuse_cells``): "keep" for the grid that takes
        the beams first (updates looked up and kept), "take" for the one that takes them
        second, in order (looked up; a hit forgets its entry and the older ones), "use"
        both, "off" for beams no other grid will take (:mod:`mapping.ir_memo`)."""
        if memo not in _MEMO_MODES:
            raise ValueError(f"memo must be one of {_MEMO_MODES}, got {memo!r}")
        if len(beams) == 0:
            return 0
        h, reach, ends = self._parts(beams, grid.resolution)
        if len(ends) == 1:
            return grid.add(*self._cone_updates(grid, beams, h, reach, memo))
        total, start = 0, 0
        for stop in ends:
            sub = Beams(*(getattr(beams, n)[start:stop] for n in _FIELDS))
            total += grid.add(*self._cone_updates(grid, sub, h[start:stop], reach[start:stop],
                                                  memo))  # fmt: skip
            start = stop
        return total

    def integrate_each(self, grids: list[OccupancyGrid], beams: list[Beams]) -> int:
        """``integrate(grids[i], beams[i], memo="off")`` for every i, bit for bit, for
        beams that share their range, kind and sigma arrays (the same scans at other
        poses: the drift hypotheses' maps): the lattice of their cones, which depends on
        the cones' lengths and widths only, is computed once. Returns the cell updates.
        (One computation for several grids was tried: no faster, and slower without the
        heap slack of :mod:`hilnav.heap`, its arrays being larger.)"""
        b0 = beams[0] if beams else None
        res = grids[0].resolution if grids else 0.0
        if b0 is None or len(b0) == 0 or any(
            b.range_m is not b0.range_m or b.kind is not b0.kind
            or b.sigma_rad is not b0.sigma_rad or g.resolution != res
            for g, b in zip(grids, beams, strict=True)
        ):  # fmt: skip
            return sum(self.integrate(g, b, "off") for g, b in zip(grids, beams, strict=True))
        h, reach, csum = self._bound(b0, res)
        if csum[-1] > self.max_samples_per_call:  # integrate would apply it in parts
            return sum(self.integrate(g, b, "off") for g, b in zip(grids, beams, strict=True))
        keep = (reach > 0).nonzero()[0]  # a cone of no length has no lattice point
        lat = lattice(reach[keep], h[keep], res) if len(keep) else None
        hit = b0.kind[keep] == KIND_HIT
        z = np.where(hit, b0.range_m[keep], np.nan)
        total = 0
        for grid, b in zip(grids, beams, strict=True):
            grow_for_cones(grid, b.x, b.y, h, reach)
            if lat is None:
                continue
            x, y, angle = (np.ascontiguousarray(getattr(b, n)[keep], dtype=float)
                           for n in ("x", "y", "angle"))  # fmt: skip
            cells = cone_cells(grid, x, y, angle, h[keep], reach[keep], lat)
            _, flat, dl = cell_updates(grid, self.config, (x, y), angle, hit, z, h[keep], cells)
            total += grid.add(flat, dl)
        return total
