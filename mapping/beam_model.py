"""The beam sensor model of ir-grid-mapping §4 against an occupancy grid (eq. 7-8).

The samples of the robot's pose are weighted with the likelihood of the IR readings
given the pose x and the map m built so far,

    p(z | x, m) = prod_k p(z^k | x, m)                                         (7)
    p(z^k | x, m) = a_hit p_hit + a_rand p_rand + a_max p_max                 (8)

with p_hit a Gaussian about the range z* expected by ray casting the map from the
sample, p_rand uniform over [0, z_max], and p_max the point mass of a reading that saw
nothing (``KIND_CLEAR``: it is likely where the map has no obstacle within z_max).

Against a map rather than the world: the expected range z* is the centre of the first
run of occupied cells along the ray (eq. 6 widens walls towards the robot, so the first
occupied cell is biased short), and sigma_hit (0.2 m, growing with z^2) covers the map's
wall thickness as well as the sensor's noise. Cells with p > ``occupied_p`` are
obstacles. A beam whose ray runs into never-observed cells (log-odds 0) before its range
or the expected obstacle is uninformative (:func:`unknown_p`): otherwise a pose that
throws the beams into unmapped space, or onto some other mapped wall, would beat the
true pose whose beams end where the map is still unknown. :func:`pair_ratio` compares two
poses on the beams informative for both.
"""

from __future__ import annotations

import math

import numpy as np
from edt import edtsq

from mapping.association_config import AssociationConfig
from mapping.grid import OccupancyGrid, logit
from mapping.ir_inverse import KIND_CLEAR
from mapping.se2 import compose


def expected_ranges(
    grid: OccupancyGrid, l_occ: float, world: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(z*, u*) of every beam: ray casting from the sensor poses ``world`` (P, M, 3) at
    the ranges ``t`` (T,) through the cells with log-odds above ``l_occ``; z* is the
    centre of the first run of occupied cells (inf for a beam that meets none), u* the
    range of the first cell never observed (log-odds 0, or outside the map; inf if none)."""
    ox, oy = world[..., 0][..., None], world[..., 1][..., None]
    c, s = np.cos(world[..., 2])[..., None], np.sin(world[..., 2])[..., None]
    row, col = grid.cell_of(ox + c * t, oy + s * t)  # (P, M, T)
    inside = grid.inside(row, col)
    rows, cols = grid.shape
    lo = grid.logodds.reshape(-1)
    flat = np.where(inside, row * cols + col, 0)
    cell = lo[flat]
    hit = inside & (cell > l_occ)
    unknown = ~inside | (cell == 0.0)
    u_star = np.where(unknown.any(axis=-1), t[np.argmax(unknown, axis=-1)], np.inf)
    any_hit = hit.any(axis=-1)
    # The expected range is the centre of the first run of occupied cells: eq. 6 widens
    # walls towards the robot, and the first occupied cell would be biased short.
    first = np.argmax(hit, axis=-1)
    started = np.arange(len(t)) >= first[..., None]
    run = started & (np.cumsum(started & ~hit, axis=-1) == 0)
    first = first + (run.sum(axis=-1) - 1) // 2
    return np.where(any_hit, t[first], np.inf), u_star  # (P, M) each


class BeamModel:
    """Eq. 7-8 with the parameters of an :class:`AssociationConfig`."""

    def __init__(self, cfg: AssociationConfig) -> None:
        self.cfg = cfg
        self.l_occ = logit(cfg.occupied_p)

    def log_likelihood(
        self,
        grid: OccupancyGrid,
        poses: np.ndarray,
        sens: np.ndarray,
        ranges: np.ndarray,
        kinds: np.ndarray,
    ) -> np.ndarray:
        """Eq. 7-8: sum over beams of log p(z^k | x, m) for each pose (P, 3), the beams
        given by their sensor poses ``sens`` (M, 3) in the robot frame, ``ranges`` and
        ``kinds`` (M,); ray casting in ``grid``."""
        return self.terms(grid, poses, sens, ranges, kinds)[0].sum(axis=-1)

    def terms(
        self,
        grid: OccupancyGrid,
        poses: np.ndarray,
        sens: np.ndarray,
        ranges: np.ndarray,
        kinds: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(log p(z^k | x, m), blind) per pose and beam (P, M): blind beams run into
        never-observed space first and carry :func:`unknown_p`."""
        cfg = self.cfg
        res = grid.resolution
        world = compose(poses[:, None, :], sens[None, :, :])  # (P, M, 3)
        z_max = cfg.max_range_m
        t = np.arange(0.5 * res, z_max + 3 * cfg.sigma_hit_m, res)
        z_star, u_star = expected_ranges(grid, self.l_occ, world, t)
        z = np.broadcast_to(ranges[None, :], z_star.shape)
        sig = np.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * np.nan_to_num(z, nan=z_max) ** 2)
        clear_k = (kinds == KIND_CLEAR)[None, :]
        # A beam that runs into never-observed cells before its range (z_max for a clear
        # reading) or the expected obstacle tells nothing about the pose: uninformative.
        reach = np.where(clear_k, z_max, np.nan_to_num(z, nan=z_max) - 1.5 * sig)
        blind = u_star < np.minimum(reach, z_star)
        with np.errstate(invalid="ignore", over="ignore"):
            p_hit = np.where(
                np.isfinite(z_star),
                np.exp(-0.5 * ((z - z_star) / sig) ** 2) / (sig * math.sqrt(2 * math.pi)),
                0.0,
            )
        p_rand = 1.0 / z_max
        clear = (kinds == KIND_CLEAR)[None, :]
        sig_max = math.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * z_max**2)
        p_max = (z_star > z_max - sig_max).astype(float)
        p = np.where(
            clear,
            cfg.a_max * p_max + cfg.a_rand * p_rand,
            cfg.a_hit * np.nan_to_num(p_hit) + cfg.a_rand * p_rand,
        )
        p = np.where(blind, unknown_p(cfg, clear), p)
        return np.log(p), blind


def distance_cells(free: np.ndarray) -> np.ndarray:
    """Euclidean distance (cells, float64) of every ``True`` cell of ``free`` to the
    nearest ``False`` one: exactly scipy.ndimage's ``distance_transform_edt``.

    By the ``edt`` library (its import costs a few milliseconds and 2 MiB, scipy.ndimage's
    a quarter of a second and 26 MiB: a tenth of the daemon's memory and of a replay's
    time; it is also about twice as fast on the association's windows): its squared
    distances are sums of squared integer offsets, exact in its float32 below 2^24, and
    the square root is taken in float64, as scipy takes it. A field too large for that
    (over 2,896 cells across) goes to scipy. Without an obstacle every distance is
    infinite (edt's own answer; scipy's is not, so that case does not go to it)."""
    rows, cols = free.shape
    if rows * rows + cols * cols < 1 << 24:
        return np.sqrt(edtsq(free, black_border=False, parallel=1), dtype=np.float64)
    if free.all():
        return np.full(free.shape, np.inf)
    from scipy.ndimage import distance_transform_edt

    return distance_transform_edt(free)


def unknown_p(cfg: AssociationConfig, clear: np.ndarray) -> np.ndarray:
    """The likelihood of a reading whose beam runs into never-observed space: uniform
    over the range for a return, an even chance of p_max for a reading that saw nothing
    (so that looking into unmapped space is neither rewarded nor punished)."""
    p_rand = 1.0 / cfg.max_range_m
    return np.where(clear, 0.5 * cfg.a_max + cfg.a_rand * p_rand, p_rand)


class FieldBeamModel:
    """Eq. 7-8 evaluated on a distance field of the map: fast enough for the sample
    search of the association (hundreds of poses, tens of beams, many rounds).

    The expected range is not ray cast for every sample: the distance from a beam's
    endpoint to the nearest obstacle stands for |z - z*| in p_hit (exact for a surface
    square to the beam), and a beam whose ray meets an obstacle more than ``sigma_hit``
    before its range is occluded (p_hit = 0, as a ray cast z* well short of z gives).
    A reading that saw nothing (``KIND_CLEAR``) gets p_max when its ray is free of
    obstacles up to z_max. A beam that runs into never-observed cells first is
    uninformative (:func:`unknown_p`), as in :class:`BeamModel`. Obstacles are the cells
    with p > ``occupied_p``; the field is computed once per map (:meth:`set_map`, the
    Euclidean distance transform of :func:`distance_cells`).
    """

    def __init__(self, cfg: AssociationConfig, step_m: float = 0.2) -> None:
        self.cfg = cfg
        self.l_occ = logit(cfg.occupied_p)
        self.step_m = step_m
        self.dist: np.ndarray | None = None
        self.known: np.ndarray | None = None
        self.origin = (0.0, 0.0)
        self.res = 1.0
        self._tables: tuple[np.ndarray, np.ndarray] | None = None

    def set_map(
        self, grid: OccupancyGrid, box: tuple[float, float, float, float] | None = None
    ) -> None:
        """The distance field of ``grid``, or of its part inside ``box`` (xmin, ymin,
        xmax, ymax: where the samples' beams can reach; cheaper on a large map)."""
        self.res = grid.resolution
        r0, c0 = 0, 0
        lo = grid.logodds
        if box is not None:
            (ra, rb), (ca, cb) = grid.cell_of(
                np.array([box[0], box[2]]), np.array([box[1], box[3]])
            )
            rows, cols = grid.shape
            r0, r1 = max(0, int(ra)), min(rows, int(rb) + 1)
            c0, c1 = max(0, int(ca)), min(cols, int(cb) + 1)
            lo = lo[r0 : max(r1, r0 + 1), c0 : max(c1, c0 + 1)]
        occ = lo > self.l_occ
        self._tables = None
        self.known = lo != 0.0
        self.origin = (grid.origin[0] + c0 * self.res, grid.origin[1] + r0 * self.res)
        self.dist = (distance_cells(~occ) * self.res).astype(np.float32)

    def _index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat indices of world points into the field framed by one cell that stands
        for everything outside it (a point outside lands on that frame: clipped)."""
        assert self.dist is not None and self.known is not None
        rows, cols = self.dist.shape
        if self._tables is None:
            # The field, and the cells' codes (1: an obstacle within 0.75 cell, i.e. an
            # obstacle cell; 2: observed), framed: outside is infinitely far and unknown.
            dist = np.full((rows + 2, cols + 2), np.inf, dtype=np.float32)
            dist[1:-1, 1:-1] = self.dist
            code = np.zeros((rows + 2, cols + 2), dtype=np.uint8)
            code[1:-1, 1:-1] = (self.dist < 0.75 * self.res) | (self.known.astype(np.uint8) << 1)
            self._tables = (dist.ravel(), code.ravel())
        c = np.subtract(x, self.origin[0])
        c /= self.res
        np.floor(c, out=c)
        r = np.subtract(y, self.origin[1], out=np.empty_like(c))
        r /= self.res
        np.floor(r, out=r)
        # The frame's cell 0 is the field's -1: the same floors as the field's own cells.
        c += 1.0
        np.clip(c, 0.0, cols + 1.0, out=c)
        r += 1.0
        np.clip(r, 0.0, rows + 1.0, out=r)
        r *= cols + 2
        r += c
        return r.astype(np.intp)

    def _lookup(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance to the nearest obstacle at world points (inf outside the map)."""
        idx = self._index(x, y)
        assert self._tables is not None
        return self._tables[0].take(idx)

    def log_likelihood(
        self, poses: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
    ) -> np.ndarray:
        """Sum over beams of log p(z^k | x, m) for each pose (P, 3); beams as in
        :meth:`BeamModel.log_likelihood` (robot-frame sensor poses, ranges, kinds)."""
        return self.terms(poses, sens, ranges, kinds)[0].sum(axis=-1)

    def terms(
        self, poses: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(log p, blind) per pose and beam (P, M), as :meth:`BeamModel.terms`."""
        cfg = self.cfg
        z_max = cfg.max_range_m
        world = compose(poses[:, None, :], sens[None, :, :])  # (P, M, 3)
        c, s = np.cos(world[..., 2]), np.sin(world[..., 2])
        clear = kinds == KIND_CLEAR
        z = np.where(clear, z_max, np.nan_to_num(ranges, nan=z_max))
        sig = np.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * z**2)
        d_end = self._lookup(world[..., 0] + c * z, world[..., 1] + s * z)
        # The ray up to its range less 1.5 sigma (or up to z_max for a clear reading).
        t = np.arange(self.step_m, z_max + 1e-9, self.step_m)
        reach = np.where(clear, z_max, z - 1.5 * sig)
        px = world[..., 0][..., None] + c[..., None] * t
        py = world[..., 1][..., None] + s[..., None] * t
        idx = self._index(px, py)
        assert self._tables is not None
        code = self._tables[1].take(idx)
        # The first obstacle and the first never-observed cell along each ray. The ray up
        # to ``reach`` is a prefix of it: blocked when the first obstacle lies on it, blind
        # when the first unknown cell lies on it before the first obstacle.
        wall, unknown = code == 3, code == 0  # an obstacle cell is observed
        iw = np.argmax(wall, axis=-1)[..., None]
        iu = np.argmax(unknown, axis=-1)[..., None]
        first_wall = np.where(np.take_along_axis(wall, iw, -1)[..., 0], t[iw[..., 0]], np.inf)
        t_unk = np.where(np.take_along_axis(unknown, iu, -1)[..., 0], t[iu[..., 0]], np.inf)
        blocked = first_wall <= reach[None, :]
        first_unk = np.where(t_unk <= reach[None, :], t_unk, np.inf)
        blind = first_unk < first_wall
        with np.errstate(over="ignore"):
            p_hit = np.exp(-0.5 * (d_end / sig) ** 2) / (sig * math.sqrt(2 * math.pi))
        p_hit = np.where(blocked, 0.0, p_hit)
        p_rand = 1.0 / z_max
        p = np.where(
            clear[None, :],
            cfg.a_max * (~blocked) + cfg.a_rand * p_rand,
            cfg.a_hit * p_hit + cfg.a_rand * p_rand,
        )
        p = np.where(blind, unknown_p(cfg, clear[None, :]), p)
        return np.log(p), blind


def pair_ratio(terms: tuple[np.ndarray, np.ndarray], temperature: float) -> tuple[float, int]:
    """Tempered log-likelihood ratio of pose 0 over pose 1 from their beam ``terms``
    (2, M), on the beams that see observed space from both poses (a beam that looks into
    unmapped space from one of them is evidence for neither), and how many beams that is."""
    lp, blind = terms
    both = ~blind[0] & ~blind[1]
    return float(np.sum((lp[0] - lp[1])[both])) / temperature, int(both.sum())
