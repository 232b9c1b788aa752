"""Sharp GP2Y0A710K0F infrared range sensor: voltage <-> range, validity flags, median filter.

The datasheet curve (shared/protocols/sensors.md, as encoded in the Webots sensor model)
is interpolated piecewise-linearly in 1/d, where the curve is nearly linear. A
per-sensor calibration table can replace it (:class:`SharpCurve`). The sensor is valid
from 1.0 to 5.5 m: below 1.0 m the reading is flagged ``too_near``, beyond 5.5 m
``too_far``, and a voltage under the no-return level (nothing reflected) ``no_return``;
nothing is silently clamped.

The forward model :meth:`SharpCurve.voltage` also covers what the inverse cannot see:
the curve peaks near 0.5 m and the voltage *falls* again for nearer obstacles, so an
obstacle at 0.2 m reads like one several metres away (the near-range ambiguity the
IR-mapping paper observed). The fakes use it to produce realistic voltages.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

# Datasheet curve: distance (m) -> output voltage (V).
DATASHEET_M = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.3, 2.6, 2.9, 3.2,
               3.5, 3.8, 4.1, 4.4, 4.7, 5.0, 5.5)  # fmt: skip
DATASHEET_V = (3.13, 3.08, 3.00, 2.80, 2.60, 2.50, 2.30, 2.10, 2.00, 1.90, 1.80, 1.70, 1.63,
               1.57, 1.52, 1.50, 1.47, 1.44, 1.42, 1.40, 1.39, 1.37)  # fmt: skip

MIN_VALID_M = 1.0
MAX_VALID_M = 5.5
NO_RETURN_V = 1.2  # below this nothing was reflected (the curve reaches ~1.3 V near 8 m)
BASELINE_V = 1.0  # output with no reflection at all
# Below the peak the output falls roughly linearly with distance (beam spot off the PSD).
NEAR_EXPONENT = 0.8


@dataclass(frozen=True)
class SharpCurve:
    """A voltage-distance table, strictly decreasing in voltage beyond its first point."""

    distances_m: tuple[float, ...] = DATASHEET_M
    voltages_v: tuple[float, ...] = DATASHEET_V
    min_valid_m: float = MIN_VALID_M
    max_valid_m: float = MAX_VALID_M
    no_return_v: float = NO_RETURN_V
    _inv_d: np.ndarray = field(init=False, repr=False, compare=False)
    _v: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        d = np.asarray(self.distances_m, dtype=float)
        v = np.asarray(self.voltages_v, dtype=float)
        if d.shape != v.shape or len(d) < 2:
            raise ValueError("calibration table needs matching distances and voltages (>= 2)")
        if np.any(np.diff(d) <= 0):
            raise ValueError("calibration distances must increase strictly")
        object.__setattr__(self, "_inv_d", 1.0 / d)
        object.__setattr__(self, "_v", v)

    @property
    def peak_m(self) -> float:
        return float(self.distances_m[int(np.argmax(self._v))])

    def voltage(self, distance_m: np.ndarray | float) -> np.ndarray:
        """Forward model: the output voltage for true distances (inf = nothing there)."""
        d = np.asarray(distance_m, dtype=float)
        out = np.full(d.shape, BASELINE_V)
        finite = np.isfinite(d) & (d > 0)
        peak = self.peak_m
        vmax = float(self._v.max())
        far = finite & (d >= peak)
        # np.interp needs increasing x: 1/d decreases with d, so reverse the table.
        x = self._inv_d[::-1]
        y = self._v[::-1]
        inv = 1.0 / np.where(far, d, 1.0)
        v_far = np.interp(inv, x, y)
        # Beyond the table: continue in 1/d towards the baseline at infinity.
        last_d, last_v = self.distances_m[-1], self.voltages_v[-1]
        beyond = far & (d > last_d)
        v_far = np.where(beyond, BASELINE_V + (last_v - BASELINE_V) * last_d * inv, v_far)
        out = np.where(far, v_far, out)
        near = finite & (d < peak)
        out = np.where(near, vmax * (np.where(near, d, peak) / peak) ** NEAR_EXPONENT, out)
        return out

    def range(self, voltage_v: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Inverse model: (ranges_m, status codes) for measured voltages.

        Status codes: 0 ok, 1 too_near, 2 too_far, 3 no_return, 4 invalid (above the
        curve's peak: impossible for a working sensor). Ranges are the curve's reading
        (nan where the voltage cannot be read as a distance).
        """
        v = np.asarray(voltage_v, dtype=float)
        x = self._v[::-1]  # increasing voltages
        y = self._inv_d[::-1]
        last_d, last_v = self.distances_m[-1], self.voltages_v[-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.interp(v, x, y)
            d = 1.0 / inv
            beyond = (v < last_v) & (v > BASELINE_V)
            d = np.where(beyond, last_d * (last_v - BASELINE_V) / (v - BASELINE_V), d)
        status = np.zeros(v.shape, dtype=np.int8)
        status[d < self.min_valid_m] = 1
        status[d > self.max_valid_m] = 2
        status[v < self.no_return_v] = 3
        status[(v > float(self._v.max())) | ~np.isfinite(v)] = 4
        d = np.where(status >= 3, np.nan, d)
        return d, status


STATUS_NAMES = ("ok", "too_near", "too_far", "no_return", "invalid")


class MedianFilter:
    """Median of the last ``n`` ranges per channel (nan readings are left out).

    Plain Python on a handful of floats per scan: the same values as ``np.median`` (the
    middle one, or the mean of the two middle ones), without numpy's per-call cost."""

    def __init__(self, channels: int, n: int = 3) -> None:
        if n < 1:
            raise ValueError("median window must be >= 1")
        self._buf: list[deque[float]] = [deque(maxlen=n) for _ in range(channels)]

    def __call__(self, ranges_m: Sequence[float]) -> list[float]:
        out = []
        for buf, r in zip(self._buf, ranges_m, strict=True):
            buf.append(float(r))
            vals = sorted(x for x in buf if math.isfinite(x))
            k = len(vals)
            if not k:
                out.append(math.nan)
            elif k % 2:
                out.append(vals[k // 2])
            else:
                out.append((vals[k // 2 - 1] + vals[k // 2]) / 2)
        return out
