"""Point (non-interval) odometry model of ekf-vs-cp.txt eq. (1)-(2), its Jacobians, and
the inverse that recovers wheel displacements from two odometry poses.

State s = (x, y, theta), input u = (dSr, dSl) (right, left wheel displacement, metres):

    dS = (dSr + dSl) / 2,   dth = (dSr - dSl) / e                         (1)
    x' = x + dS c cos(theta + kappa dth),  y' = y + dS c sin(theta + kappa dth),
    theta' = theta + dth                                                  (2)

kappa = 1, c = 1 is eq. (2) as printed; the default kappa = 1/2, c = sin(dth/2)/(dth/2)
is the exact chord of a constant-curvature arc. ``A = df/ds`` and ``W = df/du`` are the
Jacobians of the EKF's eq. (4). The model in the step (dS, dth) and its Jacobians are
numerics.motion's; here they are taken in the wheels' (dSr, dSl).
"""

from __future__ import annotations

import math

import numpy as np

from msgs import Pose2D, wrap_angle
from numerics.motion import chord_factor, wheels_to_step
from numerics.motion import motion as step_motion
from numerics.motion import motion_jacobians as step_jacobians


def motion(
    s: np.ndarray, u: np.ndarray, e: float, kappa: float = 0.5, chord: bool = True
) -> np.ndarray:
    """f(s, u) of eq. (2); theta is not wrapped (the filters keep it continuous)."""
    dsr, dsl = u
    return step_motion(s, wheels_to_step(dsl, dsr, e), kappa, chord)


def motion_jacobians(
    s: np.ndarray, u: np.ndarray, e: float, kappa: float = 0.5, chord: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """A = df/ds (3x3) and W = df/du (3x2) at (s, u)."""
    dsr, dsl = u
    a, g = step_jacobians(s, wheels_to_step(dsl, dsr, e), kappa, chord)
    # W = G d(ds, dth)/d(dSr, dSl), the chain through (1), column by column.
    w = np.stack([0.5 * g[:, 0] + g[:, 1] / e, 0.5 * g[:, 0] - g[:, 1] / e], axis=1)
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
    c = chord_factor(dth)[0] if chord else 1.0
    ds = chordlen / c
    return ds + 0.5 * e * dth, ds - 0.5 * e * dth
