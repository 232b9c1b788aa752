"""Bounded re-insertion after a correction of the sample-based data association
(ir-grid-mapping §4, fig. 11 e and 12: the range data since the last correction are
re-aligned and re-inserted).

Beyond the paper, memory and time stay bounded:

- snapshots: a copy of the map every ``snapshot_every_m`` of travel, only those within
  the last ``reinsert_m`` kept (:func:`keep_snapshot`), each as (the first scan not in
  it, the travel then, the map);
- re-alignment (:func:`realign`): an accepted correction moves the scans since the
  oldest snapshot kept (the ramp of :func:`mapping.loop_correction.realigned_poses`), and
  the later snapshots are dropped (they hold the old poses);
- the rebuild (:class:`Rebuild`): the moved scans are re-inserted into a copy of that
  snapshot, ``reinsert_per_step`` scans per step, first into the reference map (those
  older than ``ref_lag_m``), then into a copy of it that becomes the map; the old maps
  are used until the rebuilt ones have caught up, so no step stalls. Exact: nothing is
  "un-inserted" from clamped log-odds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.grid import OccupancyGrid
from mapping.ir_inverse import IrInverseModel
from mapping.loop_correction import realigned_poses
from mapping.scan_records import ScanRecords

Snapshot = tuple[int, float, OccupancyGrid]
"""(the first scan not in the map, the travel then, the map)."""


def keep_snapshot(
    snaps: list[Snapshot], n: int, travel: float, grid: OccupancyGrid, cfg: AssociationConfig
) -> None:
    """A copy of ``grid`` (holding the scans before ``n``) if the last snapshot is
    ``snapshot_every_m`` back; only the snapshots within ``reinsert_m`` are kept."""
    if travel - snaps[-1][1] >= cfg.snapshot_every_m:
        snaps.append((n, travel, grid.copy()))
        while len(snaps) > 1 and snaps[0][1] < travel - cfg.reinsert_m:
            snaps.pop(0)


@dataclass
class Rebuild:
    """A map being rebuilt from a snapshot after a correction: the scans from ``start``
    are re-inserted, up to ``cursor`` so far, first into ``ref`` (those older than the
    reference lag), then into ``grid`` (a copy of it, holding the rest)."""

    start: int
    cursor: int
    ref: OccupancyGrid
    grid: OccupancyGrid | None = None
    ref_upto: int = 0

    def advance(
        self, rec: ScanRecords, model: IrInverseModel, aged_travel: float, per_step: int
    ) -> int:
        """Re-insert up to ``per_step`` scans (those taken before ``aged_travel`` into the
        reference map); returns the cell updates. :attr:`done` once caught up."""
        updates = 0
        cut = rec.older_than(self.cursor, aged_travel)
        stop = min(len(rec), self.cursor + per_step)
        while self.cursor < stop:
            if self.grid is None and self.cursor >= cut:
                self.grid, self.ref_upto = self.ref.copy(), self.cursor
            target = self.ref if self.grid is None else self.grid
            end = stop if self.grid is not None else min(stop, cut)
            updates += model.integrate(target, rec.beams(self.cursor, end), "off")
            self.cursor = end
        if self.cursor >= len(rec) and self.grid is None:
            self.grid, self.ref_upto = self.ref.copy(), self.cursor
        return updates

    def done(self, rec: ScanRecords) -> bool:
        return self.cursor >= len(rec)


def realign(
    rec: ScanRecords,
    snaps: list[Snapshot],
    travel: float,
    corrected: np.ndarray,
    cfg: AssociationConfig,
) -> tuple[Rebuild, list[Snapshot], int]:
    """Re-align the scans since the oldest snapshot within ``reinsert_m`` so that the
    last pose is ``corrected``; returns the rebuild from that snapshot, the snapshots
    kept and the number of scans moved."""
    inside = [sn for sn in snaps if sn[1] >= travel - cfg.reinsert_m]
    a, _, snap = inside[0] if inside else snaps[-1]
    n = len(rec)
    if n - a >= 2:
        new = realigned_poses(np.array(rec.poses[a:n]), np.array(rec.travel[a:n]), corrected)
        for i in range(a, n):
            rec.poses[i] = new[i - a]
    else:
        rec.poses[n - 1] = np.array(corrected, dtype=float)
    kept = [sn for sn in snaps if sn[0] <= a]  # the later ones hold old poses
    return Rebuild(a, a, snap.copy()), kept, n - a
