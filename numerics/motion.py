"""Differential-drive odometry of ekf-vs-cp.txt eq. (1)-(2) and its Jacobians.

Eq. (1): wheel displacements (dl, dr) (metres) give the step
    ds = (dr + dl) / 2,    dtheta = (dr - dl) / e          (e: wheel base)
Eq. (2) moves the pose (x, y, theta) by ds along a heading inside the step:
    x' = x + ds c cos(phi),  y' = y + ds c sin(phi),  theta' = theta + dtheta,
    phi = theta + kappa dtheta.
kappa = 1, c = 1 is eq. (2) as printed (heading at the end of the step); kappa = 1/2
(the midpoint) is exact for a constant-curvature step when ds is the chord, and with
``chord=True`` the factor c = sin(dtheta/2) / (dtheta/2) turns the arc length ds into
that chord. Theta is not wrapped here: a caller that keeps it in (-pi, pi] wraps it.

Jacobians (checked against finite differences in tests/test_numerics.py), with
dc = dc/d(dtheta):
    F = d(x', y', theta') / d(x, y, theta)
      = [[1, 0, -ds c sin phi], [0, 1, ds c cos phi], [0, 0, 1]]
    G = d(x', y', theta') / d(ds, dtheta)
      = [[c cos phi, ds (dc cos phi - c kappa sin phi)],
         [c sin phi, ds (dc sin phi + c kappa cos phi)],
         [0, 1]]
    J = d(ds, dtheta) / d(dl, dr) = [[1/2, 1/2], [-1/e, 1/e]]
"""

from __future__ import annotations

import math

import numpy as np


def wheels_to_step(dl: float, dr: float, wheelbase_m: float) -> np.ndarray:
    """Eq. (1): the step (ds, dtheta) of wheel displacements (dl, dr) in metres."""
    return np.array([0.5 * (dr + dl), (dr - dl) / wheelbase_m])


def step_to_wheels(ds: float, dtheta: float, wheelbase_m: float) -> np.ndarray:
    """Inverse of eq. (1): wheel displacements (dl, dr) of a step (ds, dtheta)."""
    h = 0.5 * wheelbase_m * dtheta
    return np.array([ds - h, ds + h])


def wheels_jacobian(wheelbase_m: float) -> np.ndarray:
    """J = d(ds, dtheta) / d(dl, dr) of eq. (1)."""
    return np.array([[0.5, 0.5], [-1.0 / wheelbase_m, 1.0 / wheelbase_m]])


def chord_factor(dtheta: float) -> tuple[float, float]:
    """c = sin(dtheta/2) / (dtheta/2), the chord of a unit arc turning by dtheta, and
    dc/d(dtheta); a Taylor series below |dtheta| = 2e-4."""
    h = 0.5 * dtheta
    if abs(h) < 1e-4:
        return 1.0 - h * h / 6.0, -h / 6.0  # c = 1 - dtheta^2/24, dc = -dtheta/12
    c = math.sin(h) / h
    dc = 0.5 * (math.cos(h) * h - math.sin(h)) / (h * h)
    return c, dc


def motion(state: np.ndarray, u: np.ndarray, kappa: float = 0.5, chord: bool = False) -> np.ndarray:
    """Eq. (2): the pose (x, y, theta) after the step u = (ds, dtheta); theta unwrapped."""
    x, y, th = state
    ds, dth = u
    c = chord_factor(dth)[0] if chord else 1.0
    phi = th + kappa * dth
    return np.array([x + ds * c * math.cos(phi), y + ds * c * math.sin(phi), th + dth])


def motion_jacobians(
    state: np.ndarray, u: np.ndarray, kappa: float = 0.5, chord: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """(F, G): Jacobians of :func:`motion` with respect to the state and to (ds, dtheta)."""
    th = state[2]
    ds, dth = u
    c, dc = chord_factor(dth) if chord else (1.0, 0.0)
    phi = th + kappa * dth
    cp, sp = math.cos(phi), math.sin(phi)
    f = np.array([[1.0, 0.0, -ds * c * sp], [0.0, 1.0, ds * c * cp], [0.0, 0.0, 1.0]])
    g = np.array(
        [
            [c * cp, ds * (dc * cp - c * sp * kappa)],
            [c * sp, ds * (dc * sp + c * cp * kappa)],
            [0.0, 1.0],
        ]
    )
    return f, g
