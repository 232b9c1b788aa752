"""Point (non-interval) odometry model of ekf-vs-cp.txt eq. (1)-(2), its Jacobians, and
the inverse that recovers wheel displacements from two odometry poses.

State s = (x, y, theta), input u = (dSr, dSl) (right, left wheel displacement, metres):

    dS = (dSr + dSl) / 2,   dth = (dSr - dSl) / e                         (1)
    x' = x + dS c cos(theta + kappa dth),  y' = y + dS c sin(theta + kappa dth),
    theta' = theta + dth                                                  (2)

kappa = 1, c = 1 is eq. (2) as printed; the default kappa = 1/2, c = sin(dth/2)/(dth/2)
is the exact chord of a constant-curvature arc. ``A = df/ds`` and ``W = df/du`` are the
Jacobians of the EKF's eq. (4).
"""

from __future__ import annotations

import math

import numpy as np

from msgs import Pose2D, wrap_angle


def _sinc_half(d: float) -> tuple[float, float]:
    """c = sin(d/2)/(d/2) and dc/dd."""
    h = 0.5 * d
    if abs(h) < 1e-4:
        return 1.0 - h * h / 6.0, -h / 6.0  # c = 1 - d^2/24, dc/dd = -d/12
    c = math.sin(h) / h
    dc = 0.5 * (math.cos(h) * h - math.sin(h)) / (h * h)
    return c, dc


def motion(
    s: np.ndarray, u: np.ndarray, e: float, kappa: float = 0.5, chord: bool = True
) -> np.ndarray:
    """f(s, u) of eq. (2); theta is not wrapped (the filters keep it continuous)."""
    x, y, th = s
    dsr, dsl = u
    ds = 0.5 * (dsr + dsl)
    dth = (dsr - dsl) / e
    c = _sinc_half(dth)[0] if chord else 1.0
    phi = th + kappa * dth
    return np.array([x + ds * c * math.cos(phi), y + ds * c * math.sin(phi), th + dth])


def motion_jacobians(
    s: np.ndarray, u: np.ndarray, e: float, kappa: float = 0.5, chord: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """A = df/ds (3x3) and W = df/du (3x2) at (s, u)."""
    _, _, th = s
    dsr, dsl = u
    ds = 0.5 * (dsr + dsl)
    dth = (dsr - dsl) / e
    c, dc = _sinc_half(dth) if chord else (1.0, 0.0)
    phi = th + kappa * dth
    cp, sp = math.cos(phi), math.sin(phi)
    a = np.array([[1.0, 0.0, -ds * c * sp], [0.0, 1.0, ds * c * cp], [0.0, 0.0, 1.0]])
    # d/d(ds), d/d(dth) of (x', y', th'), then the chain through (1).
    d_ds = np.array([c * cp, c * sp, 0.0])
    d_dth = np.array([ds * (dc * cp - c * sp * kappa), ds * (dc * sp + c * cp * kappa), 1.0])
    w = np.stack([0.5 * d_ds + d_dth / e, 0.5 * d_ds - d_dth / e], axis=1)
    return a, w


def wheels_from_poses(
    p0: Pose2D, p1: Pose2D, e: float, kappa: float = 0.5, chord: bool = True
) -> tuple[float, float]:
    """(dSr, dSl) that move ``p0`` to ``p1`` under eq. (1)-(2) (exact when the motion
    between them is one constant-curvature arc; the displacement is projected on the
    model's direction, so a sideways jump of the odometry is not invented)."""
    dth = wrap_angle(p1.theta - p0.theta)
    phi = p0.theta + kappa * dth
    chordlen = (p1.x - p0.x) * math.cos(phi) + (p1.y - p0.y) * math.sin(phi)
    c = _sinc_half(dth)[0] if chord else 1.0
    ds = chordlen / c
    return ds + 0.5 * e * dth, ds - 0.5 * e * dth
