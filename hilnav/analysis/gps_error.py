"""The error of a path against GPS fixes: one definition, for ``hilnav analyze`` and the
Victoria Park bench (bench/victoria_park.py).

- **GPS outlier rule** (independent of the estimate, :func:`gps_inliers`): the encoders
  say how far the vehicle travelled between two fixes; two fixes cannot be farther apart
  than that path length plus a 1.5 m allowance. A fix is an outlier if it violates this
  bound with more than half of its neighbours within +-10 s (at least 4 neighbours needed;
  fixes with fewer neighbours, i.e. isolated in the receiver's gaps, are kept).
- **The estimate at a fix** is its latest pose at or before the fix's time (the filter's
  estimate then), for the kept fixes within the estimate's time span.
- **The error** at each such fix is the distance to the fix, before and after the best
  rigid 2-D fit (rotation + translation, no scale: ``geometry.rigid_fit``) of those poses
  onto the fixes. The RMS after the fit is the absolute trajectory error (ATE RMSE) of
  SLAM evaluations; before the fit it is what counts for a path in the GPS's own frame.

Times are seconds (any common origin) or integer nanoseconds, the same unit throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hilnav.analysis.geometry import apply_fit, rigid_fit

WINDOW_S = 10.0
SLACK_M = 1.5
MIN_NEIGHBOURS = 4


def travelled_from_speed(t: np.ndarray, speed_mps: np.ndarray, ns: bool = False) -> np.ndarray:
    """Distance travelled (m) at each time ``t``: |speed| held until the next sample."""
    ts = np.asarray(t, dtype=np.float64) * (1e-9 if ns else 1.0)
    dt = np.diff(ts, append=ts[-1]) if len(ts) else ts
    steps = np.abs(np.asarray(speed_mps, dtype=np.float64)[:-1]) * dt[:-1]
    return np.concatenate([[0.0], np.cumsum(steps)])


def gps_inliers(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    travel_t: np.ndarray,
    travel_m: np.ndarray,
    window: float = WINDOW_S,
) -> np.ndarray:
    """Boolean mask of the fixes (times ``t``, positions ``x``, ``y``) kept by the outlier
    rule, the distance travelled being ``travel_m`` at times ``travel_t`` (same unit as
    ``t``; ``window`` in that unit too: 10 s, or 10e9 for nanoseconds)."""
    t = np.asarray(t, dtype=np.float64)
    s = np.interp(t, np.asarray(travel_t, dtype=np.float64), travel_m)
    keep = np.ones(len(t), dtype=bool)
    lo = np.searchsorted(t, t - window)
    hi = np.searchsorted(t, t + window, side="right")
    for i in range(len(t)):
        j = np.r_[lo[i] : i, i + 1 : hi[i]]
        if len(j) < MIN_NEIGHBOURS:
            continue
        dist = np.hypot(x[j] - x[i], y[j] - y[i])
        bad = dist > np.abs(s[j] - s[i]) + SLACK_M
        keep[i] = np.count_nonzero(bad) <= len(j) // 2
    return keep


@dataclass
class GpsErrors:
    """A path's errors at the GPS fixes it was compared with (module docstring)."""

    used: np.ndarray  # indices of the fixes used (kept and within the path's time span)
    est_x: np.ndarray  # the path's latest pose at or before each used fix
    est_y: np.ndarray
    error: np.ndarray  # distance to the fix (m)
    fit: tuple[float, float, float]  # best rigid fit (dx, dy, dtheta) of est onto the fixes
    error_fit: np.ndarray  # distance after the fit (m)

    @property
    def ate_rmse_m(self) -> float:
        return float(np.sqrt(np.mean(self.error_fit**2)))


def errors_at_fixes(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    gps_t: np.ndarray,
    gps_x: np.ndarray,
    gps_y: np.ndarray,
    keep: np.ndarray | None = None,
) -> GpsErrors | None:
    """Errors of the path (``t`` sorted, ``x``, ``y``) at the kept fixes (None: all kept);
    None when fewer than two fixes fall within the path's time span."""
    if len(t) == 0:
        return None
    inside = (gps_t >= t[0]) & (gps_t <= t[-1])
    if keep is not None:
        inside &= keep
    used = np.flatnonzero(inside)
    if len(used) < 2:
        return None
    k = np.maximum(np.searchsorted(t, gps_t[used], side="right") - 1, 0)
    ex, ey = np.asarray(x)[k], np.asarray(y)[k]
    gx, gy = gps_x[used], gps_y[used]
    fit = rigid_fit(np.column_stack([ex, ey]), np.column_stack([gx, gy]))
    fx, fy = apply_fit(fit, ex, ey)
    return GpsErrors(used, ex, ey, np.hypot(ex - gx, ey - gy), fit, np.hypot(fx - gx, fy - gy))
