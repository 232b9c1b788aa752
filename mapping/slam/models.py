"""Motion and observation models of EKF-SLAM with their Jacobians (slam-ekf.txt §4.1, §4.2.4).

Vehicle state ``xv = (x, y, theta)``: for the car it is the pose of the *laser* (eq. 12),
so that the observation model (eq. 14 onward) needs no sensor offset.

Ackermann car (eq. 11-13 and the discrete f1..f3). The rear axle centre moves with speed
``vc`` and yaw rate ``vc tan(steer) / L``; the laser sits ``a`` ahead of the rear axle and
``b`` to the left, so it moves with ``vc cos(theta) - vc tan(steer)/L (a sin + b cos)``
and ``vc sin(theta) + vc tan(steer)/L (a cos - b sin)``. Euler over ``dt`` gives f1..f3;
the paper's printed f3 lacks ``dt`` and Psi21/Psi22 have the wrong sign pattern, both
corrected here (derived, and checked against finite differences in the tests). The
encoder on a rear wheel ``H`` to the left of the centre line reads
``ve = vc (1 - tan(steer) H / L)``; the control is the *measured* ``(ve, steer)`` and the
conversion is part of the model, so Q is the noise of what was measured.

Unicycle odometry (the Pioneer): control = (distance d, heading change dtheta) of one
step, midpoint integration: ekf-vs-cp eq. (2) with kappa = 1/2, numerics.motion.

Range-bearing observation (eq. 14 onward): ``r = |m - p|``,
``phi = atan2(my - y, mx - x) - theta + bearing_offset``, with ``bearing_offset = pi/2``
for the paper's laser (0 rad along the laser's -y axis, pi/2 straight ahead) and 0 for a
sensor whose 0 rad is straight ahead. Inverse model g (augmentation, §4.2.4):
``m = p + r (cos, sin)(phi + theta - bearing_offset)``; its Jacobian with respect to z
keeps the ``- bearing_offset`` that the printed dg/dz drops.

All observation functions are vectorised over K landmarks/observations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from numerics.angles import wrap
from numerics.motion import motion, motion_jacobians

HALF_PI = 0.5 * math.pi

#: One step of a planar motion model in floats: the new pose ``(x, y, theta)``, the two
#: entries of its state Jacobian that are not those of the identity (``F[0, 2]`` and
#: ``F[1, 2]``: both models move the position by an amount that depends on the heading
#: only) and the control Jacobian G (3x2) row by row.
Step = tuple[float, float, float, float, float, float, float, float, float, float, float]


@dataclass(frozen=True, slots=True)
class AckermannGeometry:
    """Car geometry in metres (Victoria Park: see bench/victoria_park.py for the choice).

    wheelbase_m: L; laser_ahead_m: a, laser position ahead of the REAR axle;
    laser_left_m: b, laser to the left of the centre line; encoder_left_m: H, lateral
    offset of the encoder wheel to the left of the centre line (rear axle).
    """

    wheelbase_m: float = 2.83
    laser_ahead_m: float = 3.78
    laser_left_m: float = 0.5
    encoder_left_m: float = 0.76

    def __post_init__(self) -> None:
        if not self.wheelbase_m > 0:
            raise ValueError(f"wheelbase_m must be > 0, got {self.wheelbase_m}")


class AckermannModel:
    """Discrete Ackermann model of the laser pose, control ``u = (ve, steer)``."""

    control_dim = 2

    def __init__(self, geometry: AckermannGeometry | None = None) -> None:
        self.geometry = geometry or AckermannGeometry()

    def axle_speed(self, ve: float, steer: float) -> float:
        """Rear-axle-centre speed from the encoder speed: ve / (1 - tan(steer) H / L)."""
        g = self.geometry
        return ve / (1.0 - math.tan(steer) * g.encoder_left_m / g.wheelbase_m)

    def predict(
        self, xv: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (f(xv, u), df/dxv (3x3), df/du (3x2)) for one step of ``dt`` seconds."""
        return _arrays(self.step(float(xv[0]), float(xv[1]), float(xv[2]), float(u[0]),
                                 float(u[1]), float(dt)))  # fmt: skip

    def step(self, x: float, y: float, th: float, ve: float, steer: float, dt: float) -> Step:
        """:meth:`predict` in floats (see :data:`Step`): what the filter calls 40 times a
        second, without a numpy array per step."""
        g = self.geometry
        L, a, b, H = g.wheelbase_m, g.laser_ahead_m, g.laser_left_m, g.encoder_left_m
        t = math.tan(steer)
        dt_ds = 1.0 + t * t  # d tan / d steer
        den = 1.0 - t * H / L
        vc = ve / den
        dvc_dve = 1.0 / den
        dvc_ds = ve * (H / L) * dt_ds / (den * den)
        c, s = math.cos(th), math.sin(th)
        ax = a * s + b * c  # d(a cos - b sin)/dth = -ax
        ay = a * c - b * s  # d(a sin + b cos)/dth = ay
        k = t / L
        dx = vc * (c - k * ax)
        dy = vc * (s + k * ay)
        dth = vc * k
        # partials with respect to vc and to tan(steer) (through k = t / L)
        v0, v1, v2 = (c - k * ax) * dt, (s + k * ay) * dt, k * dt
        k0, k1, k2 = -vc * ax * dt, vc * ay * dt, vc * dt
        dk = dt_ds / L
        return (
            x + dt * dx, y + dt * dy, th + dt * dth,
            dt * vc * (-s - k * ay), dt * vc * (c - k * ax),
            v0 * dvc_dve, v0 * dvc_ds + k0 * dk,
            v1 * dvc_dve, v1 * dvc_ds + k1 * dk,
            v2 * dvc_dve, v2 * dvc_ds + k2 * dk,
        )  # fmt: skip


class UnicycleModel:
    """Odometry increments ``u = (d, dtheta)`` of one step (differential drive)."""

    control_dim = 2

    def predict(
        self, xv: np.ndarray, u: np.ndarray, dt: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (f(xv, u), df/dxv, df/du); ``dt`` is unused (u is already integrated)."""
        f, g = motion_jacobians(xv, u)
        return motion(xv, u), f, g

    def step(self, x: float, y: float, th: float, d: float, dth: float, dt: float = 0.0) -> Step:
        """:meth:`predict` in floats (see :data:`Step`)."""
        xn, f, g = self.predict(np.array([x, y, th]), np.array([d, dth]), dt)
        return (*map(float, xn), float(f[0, 2]), float(f[1, 2]), *map(float, g.ravel()))


def _arrays(st: Step) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f(xv, u), F, G) as arrays from a model's :data:`Step`."""
    x, y, th, f02, f12, g00, g01, g10, g11, g20, g21 = st
    fx = np.array([[1.0, 0.0, f02], [0.0, 1.0, f12], [0.0, 0.0, 1.0]])
    return np.array([x, y, th]), fx, np.array([[g00, g01], [g10, g11], [g20, g21]])


def observe(
    xv: np.ndarray, m: np.ndarray, bearing_offset: float = HALF_PI
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted (range, bearing) of landmarks ``m`` (K, 2) from vehicle pose ``xv``.

    Returns z (K, 2), dh/dxv (K, 2, 3), dh/dm (K, 2, 2). Bearings wrapped to (-pi, pi].
    """
    m = np.atleast_2d(m)
    dx = m[:, 0] - xv[0]
    dy = m[:, 1] - xv[1]
    q = dx * dx + dy * dy
    r = np.sqrt(q)
    z = np.empty((len(m), 2))
    z[:, 0] = r
    z[:, 1] = wrap(np.arctan2(dy, dx) - xv[2] + bearing_offset)
    hm = np.empty((len(m), 2, 2))
    hm[:, 0, 0] = dx / r
    hm[:, 0, 1] = dy / r
    hm[:, 1, 0] = -dy / q
    hm[:, 1, 1] = dx / q
    hv = np.empty((len(m), 2, 3))
    hv[:, :, :2] = -hm
    hv[:, 0, 2] = 0.0
    hv[:, 1, 2] = -1.0
    return z, hv, hm


def inverse_observe(
    xv: np.ndarray, z: np.ndarray, bearing_offset: float = HALF_PI
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Landmark positions g(xv, z) for observations z (K, 2) = (range, bearing).

    Returns m (K, 2), dg/dxv (K, 2, 3), dg/dz (K, 2, 2).
    """
    z = np.atleast_2d(z)
    r = z[:, 0]
    ang = z[:, 1] + xv[2] - bearing_offset
    c, s = np.cos(ang), np.sin(ang)
    m = np.empty((len(z), 2))
    m[:, 0] = xv[0] + r * c
    m[:, 1] = xv[1] + r * s
    gx = np.zeros((len(z), 2, 3))
    gx[:, 0, 0] = 1.0
    gx[:, 1, 1] = 1.0
    gx[:, 0, 2] = -r * s
    gx[:, 1, 2] = r * c
    gz = np.empty((len(z), 2, 2))
    gz[:, 0, 0] = c
    gz[:, 0, 1] = -r * s
    gz[:, 1, 0] = s
    gz[:, 1, 1] = r * c
    return m, gx, gz
