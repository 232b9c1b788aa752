"""IR range sensors emulated from a real laser scan: what a Sharp sensor at a mount would
have read, given what the laser saw from the robot at the same instant.

For every mount (x, y, yaw on the robot) the sensor's ray is sampled every ``step_m`` up
to ``reach_m``. Each sample point is seen from the laser at a bearing and a distance
(fixed for a mount, so computed once); the laser's range at that bearing (linear between
the two neighbouring beams when they lie on one surface, the nearer beam's otherwise)
says whether the point lies in front of the surface the laser saw (free) or behind it.
The ray's range is where it first passes behind the surface (interpolated between the
two samples); infinite when the laser saw the whole ray free (or saw nothing: a "no
return" reading), unknown (NaN) when a sample falls outside the laser's field of view
(one beam step of slack at each end) or on an invalid reading (<= 0) before any hit.

:class:`LaserIrBoard` turns those true ranges into the :class:`msgs.IrScan` the IR board
would report: without noise, the Sharp GP2Y0A710K0F's flags for the true range (ok in
1.0-5.5 m, too_near, too_far; unknown -> invalid); with noise, the fakes' voltage model
(:class:`fakes.world.ir_model.IrErrorModel`: near-range ambiguity, voltage noise,
dropouts, ADC) read back through the driver's own conversion and median
(:class:`drivers.irboard.convert.IrConverter`), seeded.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.irboard.convert import IrBoardConfig, IrConverter
from drivers.sharp import MAX_VALID_M, MIN_VALID_M
from fakes.world.ir_model import IrErrorModel
from msgs import IrScan


def _ray_geometry(
    mounts: np.ndarray, laser_on_robot: tuple[float, float, float], reach_m: float, step_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per mount and sample: distance along the ray t (J,), and the sample's bearing and
    distance from the laser (K, J)."""
    t = step_m * np.arange(1, int(math.ceil(reach_m / step_m)) + 1)
    lx, ly, lyaw = laser_on_robot
    px = mounts[:, 0:1] + t * np.cos(mounts[:, 2:3]) - lx
    py = mounts[:, 1:2] + t * np.sin(mounts[:, 2:3]) - ly
    c, s = math.cos(lyaw), math.sin(lyaw)
    qx, qy = c * px + s * py, -s * px + c * py
    return t, np.arctan2(qy, qx), np.hypot(qx, qy)


def ir_ranges_from_laser(
    ranges: np.ndarray,
    angles: np.ndarray,
    max_range_m: float,
    mounts: np.ndarray,
    laser_on_robot: tuple[float, float, float] = (0.0, 0.0, 0.0),
    reach_m: float = 8.0,
    step_m: float = 0.02,
    chunk: int = 256,
) -> np.ndarray:
    """True ranges (N, K) along the IR rays of ``mounts`` (K, 3) from laser scans
    ``ranges`` (N, B) at bearings ``angles`` (B, increasing, evenly spaced): finite = a
    surface, inf = free up to ``reach_m``, NaN = the laser cannot tell (see module doc)."""
    ranges = np.atleast_2d(np.asarray(ranges, dtype=float))
    angles = np.asarray(angles, dtype=float)
    mounts = np.atleast_2d(np.asarray(mounts, dtype=float))
    if ranges.shape[1] != len(angles) or len(angles) < 2:
        raise ValueError(f"laser scans have {ranges.shape[1]} readings but {len(angles)} bearings")
    if mounts.ndim != 2 or mounts.shape[1] != 3:
        raise ValueError("IR mounts must be (K, 3): x, y, yaw of each sensor on the robot")
    t, bearing, dist = _ray_geometry(mounts, laser_on_robot, reach_m, step_m)
    k, j = bearing.shape
    step_b = (angles[-1] - angles[0]) / (len(angles) - 1)
    pos = (bearing - angles[0]) / step_b  # fractional beam index
    in_fov = (pos >= -1.0) & (pos <= len(angles))
    pos = np.clip(pos, 0.0, len(angles) - 1.0)
    i0 = np.minimum(np.floor(pos).astype(np.int64), len(angles) - 2).ravel()
    w = pos.ravel() - i0
    out = np.empty((len(ranges), k))
    for a in range(0, len(ranges), chunk):
        r = ranges[a : a + chunk]
        r = np.where(r >= max_range_m, np.inf, np.where(r > 0, r, np.nan))
        r0, r1 = r[:, i0], r[:, i0 + 1]
        with np.errstate(invalid="ignore"):
            same = np.abs(r0 - r1) <= np.maximum(0.1, 0.1 * np.minimum(r0, r1))
            lin = r0 + w * (r1 - r0)
        near = np.where(w < 0.5, r0, r1)
        rr = np.where(same & np.isfinite(lin), lin, near).reshape(len(r), k, j)
        rr = np.where(in_fov[None], rr, np.nan)
        with np.errstate(invalid="ignore"):
            f = rr - dist[None]  # > 0: the laser saw past the sample point
        behind = f <= 0
        unknown = np.isnan(f)
        stop = behind | unknown
        first = np.argmax(stop, axis=-1)
        any_stop = stop.any(axis=-1)
        fi = np.take_along_axis(f, first[..., None], axis=-1)[..., 0]
        prev = np.take_along_axis(f, np.maximum(first - 1, 0)[..., None], axis=-1)[..., 0]
        hit = any_stop & np.isfinite(fi)
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = np.where((first > 0) & np.isfinite(prev), prev / (prev - fi), 1.0)
        t_hit = t[np.maximum(first - 1, 0)] + np.clip(frac, 0.0, 1.0) * step_m
        t_hit = np.where(first == 0, t[0], t_hit)
        res = np.where(hit, t_hit, np.inf)
        out[a : a + chunk] = np.where(any_stop & ~hit, np.nan, res)
    return out


class LaserIrBoard:
    """True IR ranges -> :class:`msgs.IrScan` as the board reports them (module doc)."""

    def __init__(
        self,
        channels: int,
        noise: IrErrorModel | None = None,
        median_window: int = 3,
        seed: int = 0,
        board_id: int = 1,
    ) -> None:
        self.noise = noise
        self.board_id = board_id
        self.seq = 0
        self._rng = np.random.default_rng(seed)
        self._conv: IrConverter | None = None
        if noise is not None:
            mounts = tuple((0.0, 0.0, 0.0) for _ in range(channels))
            cfg = IrBoardConfig(board_id=board_id, adc_bits=noise.adc_bits, vref_v=noise.vref_v,
                                mounts=mounts, median_window=median_window)  # fmt: skip
            self._conv = IrConverter(cfg)

    def scan(self, true_ranges_m: np.ndarray, stamp_ns: int) -> IrScan:
        r = np.asarray(true_ranges_m, dtype=float)
        seq = self.seq
        self.seq += 1
        unknown = np.isnan(r)
        if self._conv is None or self.noise is None:
            status = np.where(
                r < MIN_VALID_M, "too_near", np.where(r > MAX_VALID_M, "too_far", "ok")
            )
            status = np.where(unknown, "invalid", status)
            ranges = np.where(status == "ok", r, np.nan)
            return IrScan(stamp_ns, self.board_id, seq, tuple(float(v) for v in ranges),
                          tuple(str(s) for s in status), tuple(0.0 for _ in r))  # type: ignore[arg-type]  # fmt: skip
        counts = self.noise.counts(np.where(unknown, np.inf, r), self._rng)
        s = self._conv.scan_counts(self.board_id, seq, tuple(int(c) for c in counts), stamp_ns)
        assert s is not None
        if not unknown.any():
            return s
        status = tuple("invalid" if u else st for u, st in zip(unknown, s.status, strict=True))
        ranges = tuple(math.nan if u else v for u, v in zip(unknown, s.ranges_m, strict=True))
        return IrScan(s.stamp_ns, s.board_id, s.seq, ranges, status, s.voltages_v, s.raw_counts)  # type: ignore[arg-type]
