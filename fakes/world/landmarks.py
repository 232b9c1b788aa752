"""Simulated range-bearing landmark sensor (poles/markers in the floor plan), seeded.

The sensor sees the point landmarks of the world's floor plan (``FloorPlan.landmarks``,
e.g. the poles of ``open_field``, or :func:`pole_plan`) from a mount on a robot: within
``[min_range_m, max_range_m]`` and a field of view ``fov_rad`` centred on the mount's
axis, not hidden behind a wall (ray cast), each detected with probability ``p_detect``;
range and bearing get white Gaussian noise; ``clutter_per_scan`` spurious detections
(Poisson count, uniform in range and field of view) are added. Bearings are reported in
the convention ``bearing_zero``: "x" = 0 rad straight ahead, "y" = the paper's laser
(pi/2 straight ahead, slam-ekf.txt §4.1). The true landmark index of every reported
detection (-1 for clutter) is kept in ``last_truth`` for evaluation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fakes.world.floorplan import FloorPlan
from fakes.world.world import World
from msgs import LandmarkScan, wrap_angle


def pole_plan(
    half_size_m: float = 30.0, spacing_m: float = 6.0, jitter_m: float = 1.5, seed: int = 0
) -> FloorPlan:
    """An open square (walls at +-half_size) with poles on a jittered grid (seeded)."""
    rng = np.random.default_rng(seed)
    h = half_size_m
    segs = [(-h, -h, h, -h), (h, -h, h, h), (h, h, -h, h), (-h, h, -h, -h)]
    g = np.arange(-h + spacing_m, h - spacing_m / 2, spacing_m)
    gx, gy = np.meshgrid(g, g)
    poles = np.stack([gx.ravel(), gy.ravel()], 1) + rng.uniform(-jitter_m, jitter_m, (gx.size, 2))
    return FloorPlan("poles", np.array(segs, dtype=float), landmarks=poles)


@dataclass
class LandmarkSensorModel:
    """A range-bearing landmark detector with its error model (see module docstring)."""

    max_range_m: float = 15.0
    min_range_m: float = 0.3
    fov_rad: float = math.pi
    sigma_range_m: float = 0.05
    sigma_bearing_rad: float = math.radians(1.0)
    p_detect: float = 0.9
    clutter_per_scan: float = 0.0
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bearing_zero: str = "x"
    occlusion: bool = True
    seed: int = 0
    last_truth: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.bearing_zero not in ("x", "y"):
            raise ValueError(f"bearing_zero must be 'x' or 'y', got {self.bearing_zero!r}")
        self._rng = np.random.default_rng(self.seed)
        self.last_truth = np.zeros(0, dtype=int)

    def sensor_pose(self, world: World, robot: str) -> tuple[float, float, float]:
        """True pose (x, y, yaw) of the sensor in the map frame."""
        p = world.robots[robot].pose
        c, s = math.cos(p.theta), math.sin(p.theta)
        mx, my, myaw = self.mount
        return p.x + c * mx - s * my, p.y + s * mx + c * my, p.theta + myaw

    def scan(self, world: World, robot: str) -> LandmarkScan:
        """One noisy scan of the plan's landmarks from ``robot`` at the world's time."""
        x, y, yaw = self.sensor_pose(world, robot)
        lm = world.plan.landmarks
        rng = self._rng
        dx, dy = lm[:, 0] - x, lm[:, 1] - y
        r = np.hypot(dx, dy)
        b = np.array([wrap_angle(v) for v in np.arctan2(dy, dx) - yaw])
        seen = (r >= self.min_range_m) & (r <= self.max_range_m) & (np.abs(b) <= self.fov_rad / 2)
        if self.occlusion and seen.any():
            idx = np.nonzero(seen)[0]
            wall = world.plan.cast(
                np.tile([x, y], (len(idx), 1)), np.arctan2(dy[idx], dx[idx]), self.max_range_m
            )
            seen[idx] = wall > r[idx]
        seen &= rng.random(len(lm)) < self.p_detect
        idx = np.nonzero(seen)[0]
        rr = r[idx] + rng.normal(0.0, self.sigma_range_m, len(idx))
        bb = b[idx] + rng.normal(0.0, self.sigma_bearing_rad, len(idx))
        truth = idx.astype(int)
        n_clutter = int(rng.poisson(self.clutter_per_scan)) if self.clutter_per_scan > 0 else 0
        if n_clutter:
            rr = np.concatenate([rr, rng.uniform(self.min_range_m, self.max_range_m, n_clutter)])
            bb = np.concatenate([bb, rng.uniform(-self.fov_rad / 2, self.fov_rad / 2, n_clutter)])
            truth = np.concatenate([truth, -np.ones(n_clutter, dtype=int)])
        keep = rr > 0
        rr, bb, truth = rr[keep], bb[keep], truth[keep]
        if self.bearing_zero == "y":
            bb = bb + math.pi / 2
        order = np.argsort(bb, kind="stable")
        self.last_truth = truth[order]
        return LandmarkScan(
            stamp_ns=world.time_ns,
            ranges_m=tuple(float(v) for v in rr[order]),
            bearings_rad=tuple(float(wrap_angle(v)) for v in bb[order]),
            diameters_m=tuple(0.1 for _ in order),
            bearing_zero=self.bearing_zero,
            sensor="landmarks",
        )
