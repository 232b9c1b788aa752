"""Numerics of tracks: interpolation in time, distance travelled, start alignment, rigid fit,
relative error over a distance.

Angles of arrays are wrapped by ``numerics.angles.wrap`` (to (-pi, pi], like
``msgs.wrap_angle`` for one angle).
"""

from __future__ import annotations

import math

import numpy as np

from numerics.angles import wrap


def interp_pose(
    ref_t: np.ndarray, ref_x: np.ndarray, ref_y: np.ndarray, ref_th: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reference pose at times ``t`` (linear; heading unwrapped first); mask of t in range."""
    ok = (t >= ref_t[0]) & (t <= ref_t[-1]) if len(ref_t) else np.zeros(len(t), bool)
    tf, rf = t.astype(float), ref_t.astype(float)
    x = np.interp(tf, rf, ref_x)
    y = np.interp(tf, rf, ref_y)
    th = (
        wrap(np.interp(tf, rf, np.unwrap(ref_th)))
        if np.all(np.isfinite(ref_th))
        else np.full(len(t), np.nan)
    )
    return x, y, th, ok


def path_length(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Cumulative distance along a path (m), 0 at the first point."""
    if len(x) == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])


def align_at_start(
    x: np.ndarray, y: np.ndarray, th: np.ndarray, rx: float, ry: float, rth: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move a track rigidly so that its first pose equals the reference pose (rx, ry, rth)."""
    dth = rth - th[0]
    c, s = math.cos(dth), math.sin(dth)
    dx, dy = x - x[0], y - y[0]
    return rx + c * dx - s * dy, ry + s * dx + c * dy, wrap(th + dth)


def rigid_fit(p: np.ndarray, q: np.ndarray) -> tuple[float, float, float]:
    """Rotation + translation (dx, dy, dtheta) minimising sum |R p + t - q|^2 (2-D Kabsch)."""
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p - pc, q - qc
    th = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(th), math.sin(th)
    t = qc - np.array([c * pc[0] - s * pc[1], s * pc[0] + c * pc[1]])
    return float(t[0]), float(t[1]), th


def apply_fit(
    fit: tuple[float, float, float], x: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Points (x, y) moved by a rigid fit (dx, dy, dtheta) of :func:`rigid_fit`."""
    dx, dy, th = fit
    c, s = math.cos(th), math.sin(th)
    return c * x - s * y + dx, s * x + c * y + dy


def error_after_rigid_fit(p: np.ndarray, q: np.ndarray) -> float:
    """Mean distance of the positions ``p`` (N, 2+) from ``q`` after the rigid fit of p onto
    q: the error of the track's shape, whatever the frame it was drawn in."""
    fit = rigid_fit(p[:, :2], q[:, :2])
    x, y = apply_fit(fit, p[:, 0], p[:, 1])
    return float(np.mean(np.hypot(x - q[:, 0], y - q[:, 1])))


def relative_error(p: np.ndarray, q: np.ndarray, dist_m: float) -> float:
    """Mean error of the motions over ``dist_m`` of the reference's travel (the
    translation part of the relative error of Kuemmerle et al., 2009, "On measuring the
    accuracy of SLAM algorithms"): from each pose i to the first pose j at least
    ``dist_m`` further along ``q``, the displacement in the frame of pose i, estimated
    (``p``, (N, 3)) against reference (``q``). A frame error common to the whole track
    (a turn or shift of the start) does not count; what the track gets wrong locally
    does. NaN when the reference never travels ``dist_m``."""
    d = path_length(q[:, 0], q[:, 1])
    j = np.searchsorted(d, d + dist_m)
    i = np.nonzero(j < len(d))[0]
    if len(i) == 0:
        return math.nan
    j = j[i]

    def local(t: np.ndarray) -> np.ndarray:
        dx, dy = t[j, 0] - t[i, 0], t[j, 1] - t[i, 1]
        c, s = np.cos(t[i, 2]), np.sin(t[i, 2])
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy])

    e = local(p) - local(q)
    return float(np.mean(np.hypot(e[:, 0], e[:, 1])))
