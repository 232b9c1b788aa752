"""The cell updates of beams already computed, kept to insert them into a second grid.

Sample-based data association (:mod:`mapping.association`) inserts every scan twice:
into the map when it is taken, and into the reference map ``ref_lag_m`` of travel
later, at the same pose, with the same heading sigma. A beam's updates (its cells and
their float64 increments, :mod:`mapping.ir_cone`) depend only on the beam's six numbers,
the grid's origin and resolution and the model's parameters, and not on the other beams
of a call nor on the grid's extent. So they are kept, keyed by exactly those numbers
(their bytes), and taken again when the same beam meets a grid with the same origin:
the same cells and the same increments, bit for bit, without the work. A beam whose
pose was re-aligned since, or a grid that grew to another origin, simply misses.

Who keeps and who forgets (``keep``, ``forget`` of :meth:`UpdateMemo.updates`): the grid
that takes the beams first keeps them and forgets nothing; the grid that takes them
second, in order, keeps nothing new, and a hit there removes its entry and every older
one (an older entry will not be asked for again). The first grid must not forget: a
robot standing still repeats its beams bit for bit (the same pose, the same quantized
ranges), and a hit there would remove the entries the second grid has not taken yet
(before this rule the demo's reference map reused 11 % of its beams; now most).

Memory is bounded: at most ``max_cells`` cell updates are kept; a new beam that does not
fit removes the oldest entries, so entries that will never be asked for (of poses
re-aligned since, or of a grid that grew to another origin) do not stay.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from mapping.grid import OccupancyGrid

# (cells of each beam, their flat indices, their increments) of beams given by index.
Compute = Callable[[np.ndarray | slice], tuple[np.ndarray, np.ndarray, np.ndarray]]


class UpdateMemo:
    """Per-beam cell updates, by the beam's bytes and the grid's origin and resolution."""

    def __init__(self, max_cells: int) -> None:
        self.max_cells = int(max_cells)
        self.cells = 0
        self.hits = 0
        self.misses = 0
        # key -> (flat indices in a grid of ``cols`` columns, increments, cols), oldest first
        self._kept: dict[bytes, tuple[np.ndarray, np.ndarray, int]] = {}

    def updates(
        self,
        grid: OccupancyGrid,
        beams: np.ndarray,
        compute: Compute,
        keep: bool = True,
        forget: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(flat indices, increments) of the beams (rows of ``beams``: x, y, angle, range,
        kind, sigma), beam after beam; ``compute(indices)`` gives those not kept. ``keep``:
        keep the beams computed; ``forget``: a hit removes its entry and every older one
        (the grid that takes the beams second, in order). The grid that takes them first
        must not forget: a robot standing still repeats its beams bit for bit, and its
        hits would remove the entries the second grid has not taken yet."""
        cols = grid.shape[1]
        head = struct.pack("<3d", grid.origin[0], grid.origin[1], grid.resolution)
        keys = [head + b.tobytes() for b in np.ascontiguousarray(beams, dtype=np.float64)]
        found = [self._kept.get(k) for k in keys]
        missing = [i for i, f in enumerate(found) if f is None]
        self.hits += len(keys) - len(missing)
        self.misses += len(missing)
        if forget and len(missing) < len(keys):
            self._forget_upto(keys[max(i for i, f in enumerate(found) if f is not None)])
        if missing:
            every = len(missing) == len(keys)
            per, flat, dl = compute(slice(None) if every else np.array(missing))
            ends = np.cumsum(per)
            small = np.int64 if cols * grid.shape[0] >= 2**31 else np.int32
            for i, a, b in zip(missing, ends - per, ends, strict=True):
                found[i] = (flat[a:b], dl[a:b], cols)
                if keep and keys[i] not in self._kept and b - a <= self.max_cells:
                    while self.cells + (b - a) > self.max_cells:  # the oldest make room
                        self.cells -= len(self._kept.pop(next(iter(self._kept)))[0])
                    self._kept[keys[i]] = (flat[a:b].astype(small), dl[a:b].copy(), cols)
                    self.cells += int(b - a)
            if every:
                return flat, dl
        parts = [_in_grid(f, cols) for f in found if f is not None]
        if len(parts) == 1:
            return parts[0]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _forget_upto(self, stop: bytes) -> None:
        """Remove the entry of ``stop`` and every entry older than it."""
        while self._kept:
            key = next(iter(self._kept))
            self.cells -= len(self._kept.pop(key)[0])
            if key == stop:
                return


def _in_grid(entry: tuple[np.ndarray, np.ndarray, int], cols: int) -> tuple[np.ndarray, np.ndarray]:
    """An entry's (flat indices, increments) for a grid of ``cols`` columns (same origin)."""
    flat, dl, kept_cols = entry
    flat = flat.astype(np.int64)
    if kept_cols != cols:
        row = flat // kept_cols
        flat = row * cols + (flat - row * kept_cols)
    return flat, dl
