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
obstacles, all others free.
"""

from __future__ import annotations

import math

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.grid import OccupancyGrid, logit
from mapping.ir_inverse import KIND_CLEAR
from mapping.se2 import compose


def expected_ranges(
    grid: OccupancyGrid, l_occ: float, world: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """z* of every beam: ray casting from the sensor poses ``world`` (P, M, 3) at the
    ranges ``t`` (T,) through the cells with log-odds above ``l_occ``; inf for a beam
    that meets no obstacle. The centre of the first run of occupied cells is returned."""
    ox, oy = world[..., 0][..., None], world[..., 1][..., None]
    c, s = np.cos(world[..., 2])[..., None], np.sin(world[..., 2])[..., None]
    row, col = grid.cell_of(ox + c * t, oy + s * t)  # (P, M, T)
    inside = grid.inside(row, col)
    rows, cols = grid.shape
    occ = (grid.logodds > l_occ).reshape(-1)
    flat = np.where(inside, row * cols + col, 0)
    hit = inside & occ[flat]
    any_hit = hit.any(axis=-1)
    # The expected range is the centre of the first run of occupied cells: eq. 6 widens
    # walls towards the robot, and the first occupied cell would be biased short.
    first = np.argmax(hit, axis=-1)
    started = np.arange(len(t)) >= first[..., None]
    run = started & (np.cumsum(started & ~hit, axis=-1) == 0)
    first = first + (run.sum(axis=-1) - 1) // 2
    return np.where(any_hit, t[first], np.inf)  # (P, M)


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
        cfg = self.cfg
        res = grid.resolution
        world = compose(poses[:, None, :], sens[None, :, :])  # (P, M, 3)
        z_max = cfg.max_range_m
        t = np.arange(0.5 * res, z_max + 3 * cfg.sigma_hit_m, res)
        z_star = expected_ranges(grid, self.l_occ, world, t)
        z = np.broadcast_to(ranges[None, :], z_star.shape)
        sig = np.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * np.nan_to_num(z, nan=z_max) ** 2)
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
        return np.log(p).sum(axis=-1)
