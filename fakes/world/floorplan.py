"""Floor plans as wall segments, with vectorised ray casting and rasterisation.

A floor plan is an (N, 4) array of segments (x0, y0, x1, y1) in metres in the ``map``
frame, plus optional point landmarks (poles). Built-in plans:

- ``paper_room``: the 7 x 7 m room of ir-grid-mapping.txt with furniture blocks;
- ``office``: an 8.9 x 7.1 m office of three rooms joined by doors;
- ``open_field``: a 200 x 200 m field with no walls inside (GPS experiments).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _box(x0: float, y0: float, x1: float, y1: float) -> list[tuple[float, float, float, float]]:
    return [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]


@dataclass(frozen=True)
class FloorPlan:
    """Wall segments (N, 4) and landmarks (M, 2) in metres; ``bounds`` = (xmin, ymin, xmax, ymax)."""

    name: str
    segments: np.ndarray
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        if len(self.segments) == 0:
            return (-1.0, -1.0, 1.0, 1.0)
        xs = self.segments[:, [0, 2]]
        ys = self.segments[:, [1, 3]]
        return (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))

    def cast(self, origins: np.ndarray, angles: np.ndarray, max_range: float) -> np.ndarray:
        """Distance from each origin (K, 2) along each angle (K,) to the nearest wall.

        Returns (K,) distances; ``inf`` where no wall is hit within ``max_range``.
        """
        origins = np.atleast_2d(np.asarray(origins, dtype=float))
        angles = np.atleast_1d(np.asarray(angles, dtype=float))
        k = angles.shape[0]
        if len(self.segments) == 0:
            return np.full(k, np.inf)
        d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (K, 2)
        p = self.segments[:, :2][None, :, :]  # (1, N, 2)
        s = (self.segments[:, 2:] - self.segments[:, :2])[None, :, :]  # (1, N, 2)
        o = origins[:, None, :]
        dd = d[:, None, :]
        denom = dd[..., 0] * s[..., 1] - dd[..., 1] * s[..., 0]  # (K, N)
        w = p - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * s[..., 1] - w[..., 1] * s[..., 0]) / denom
            u = (w[..., 0] * dd[..., 1] - w[..., 1] * dd[..., 0]) / denom
        hit = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
        t = np.where(hit, t, np.inf)
        dist = t.min(axis=1)
        dist[dist > max_range] = np.inf
        return dist

    def clearance(self, x: float, y: float) -> float:
        """Distance from a point to the nearest wall segment (inf without walls)."""
        if len(self.segments) == 0:
            return float("inf")
        a = self.segments[:, :2]
        ab = self.segments[:, 2:] - a
        p = np.array([x, y])
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
        return float(np.min(np.linalg.norm(p - (a + t[:, None] * ab), axis=1)))

    def rasterize(
        self, resolution: float, origin: tuple[float, float], shape: tuple[int, int]
    ) -> np.ndarray:
        """Occupancy truth on a grid: 1 = wall, 0 = free, -1 = outside the plan's hull.

        ``shape`` is (rows, cols) with row 0 at ``origin`` y; cells are ``resolution`` m.
        Cells are walls where a segment passes within half a cell of their centre.
        """
        rows, cols = shape
        ys = origin[1] + (np.arange(rows) + 0.5) * resolution
        xs = origin[0] + (np.arange(cols) + 0.5) * resolution
        cx, cy = np.meshgrid(xs, ys)
        pts = np.stack([cx.ravel(), cy.ravel()], axis=1)
        occ = np.zeros(len(pts), dtype=bool)
        half = resolution * 0.5 * np.sqrt(2.0)
        for x0, y0, x1, y1 in self.segments:
            a = np.array([x0, y0])
            b = np.array([x1, y1])
            ab = b - a
            tt = np.clip(((pts - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
            dist = np.linalg.norm(pts - (a + tt[:, None] * ab), axis=1)
            occ |= dist <= half
        grid = np.where(occ, 1, 0).reshape(rows, cols).astype(np.int8)
        xmin, ymin, xmax, ymax = self.bounds
        outside = (cx < xmin) | (cx > xmax) | (cy < ymin) | (cy > ymax)
        grid[outside & ~occ.reshape(rows, cols)] = -1
        return grid


def paper_room() -> FloorPlan:
    """The 7 x 7 m room of the IR mapping paper, with a desk, shelves and a table."""
    segs = _box(0.0, 0.0, 7.0, 7.0)
    segs += _box(0.0, 5.6, 1.6, 7.0)  # desk in a corner
    segs += _box(5.5, 0.0, 7.0, 0.6)  # shelf along the south wall
    segs += _box(3.0, 3.0, 4.0, 4.0)  # table in the middle
    segs += _box(6.4, 4.0, 7.0, 6.0)  # cabinet on the east wall
    return FloorPlan("paper_room", np.array(segs, dtype=float), start=(1.5, 1.5, 0.0))


def office() -> FloorPlan:
    """An 8.9 x 7.1 m office: a corridor-like west room and two east rooms, doors between."""
    segs = _box(0.0, 0.0, 8.9, 7.1)
    # Wall between west (x < 4) and east rooms, with two 1 m doors.
    segs += [(4.0, 0.0, 4.0, 1.5), (4.0, 2.5, 4.0, 4.6), (4.0, 5.6, 4.0, 7.1)]
    # Wall between the two east rooms (y = 3.6), with a door.
    segs += [(4.0, 3.6, 6.0, 3.6), (7.0, 3.6, 8.9, 3.6)]
    segs += _box(1.0, 5.0, 2.5, 6.0)  # table in the west room
    segs += _box(7.6, 0.0, 8.9, 0.8)  # cabinet
    return FloorPlan("office", np.array(segs, dtype=float), start=(1.5, 1.5, 0.0))


def open_field() -> FloorPlan:
    """A 200 x 200 m field about the origin: walls far away, poles as landmarks."""
    segs = _box(-100.0, -100.0, 100.0, 100.0)
    rng = np.random.default_rng(7)
    poles = rng.uniform(-60.0, 60.0, size=(40, 2))
    return FloorPlan("open_field", np.array(segs, dtype=float), landmarks=poles)


BUILTIN = {"paper_room": paper_room, "office": office, "open_field": open_field}


def load(name: str) -> FloorPlan:
    """A built-in floor plan by name."""
    try:
        return BUILTIN[name]()
    except KeyError:
        raise ValueError(
            f"unknown floor plan {name!r}: choose one of {', '.join(sorted(BUILTIN))}"
        ) from None
