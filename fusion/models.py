"""Motion and measurement models of the pose EKF, with their Jacobians (ekf-vs-cp eq. 1-3).

Differential drive, eq. (1)-(2), from numerics.motion (Jacobians F, G, J there, checked
against finite differences in tests/test_numerics.py): wheel displacements (dl, dr) give
the step u = (ds, dtheta), and eq. (2) moves the pose by ds along the heading
theta + c dtheta. The paper prints c = 1 (heading at the end of the step); c = 1/2 (the
midpoint, default here) is exact for a constant-curvature step when ds is the chord,
which is what fusion.increments produces, and second-order accurate otherwise. The pose
EKF keeps theta wrapped to (-pi, pi], so :func:`motion` wraps it.

Wheel noise: each wheel's displacement error is white with variance k^2 |d| + floor^2
(slip and tread deformation grow with the distance rolled; Chong & Kleeman's
non-systematic odometry model), independent between wheels. Turning adds the error of the
effective wheel base (tyre scrub, floor): variance (beta dtheta)^2 on dtheta, the beta
term of ir-grid-mapping eq. (4).

Measurements: GPS position of an antenna mounted at (ax, ay) on the robot,
    h = [x + ax cos theta - ay sin theta, y + ax sin theta + ay cos theta],
    H = [[1, 0, -ax sin theta - ay cos theta], [0, 1, ax cos theta - ay sin theta]];
an absolute heading, h = theta, H = [0, 0, 1] (innovation wrapped to (-pi, pi]).

GPS bias (optional states b = (b_east, b_north)): a first-order Gauss-Markov process,
    b' = a b + w,  a = exp(-dt / tau),  Var(w) = sigma_b^2 (1 - a^2) per axis,
whose stationary standard deviation is sigma_b; the GPS then measures
h = position of the antenna + b, H = [H_position, I_2].
"""

from __future__ import annotations

import math

import numpy as np

from numerics.angles import wrap_angle
from numerics.motion import motion as unwrapped_motion
from numerics.motion import motion_jacobians, step_to_wheels, wheels_jacobian, wheels_to_step

__all__ = [
    "biased_position_measurement",
    "gauss_markov",
    "heading_measurement",
    "motion",
    "motion_jacobians",
    "position_measurement",
    "step_covariance",
    "step_to_wheels",
    "wheel_covariance",
    "wheels_jacobian",
    "wheels_to_step",
]


def wheel_covariance(dl: float, dr: float, k_m_per_sqrt_m: float, floor_m: float) -> np.ndarray:
    """2x2 covariance of (dl, dr): diag(k^2 |d| + floor^2)."""
    f2 = floor_m * floor_m
    k2 = k_m_per_sqrt_m * k_m_per_sqrt_m
    return np.diag([k2 * abs(dl) + f2, k2 * abs(dr) + f2])


def step_covariance(
    dl: float,
    dr: float,
    wheelbase_m: float,
    k_m_per_sqrt_m: float,
    floor_m: float,
    turn_fraction: float = 0.0,
) -> np.ndarray:
    """2x2 covariance of (ds, dtheta): J Q_wheels J^T, plus (beta dtheta)^2 on dtheta."""
    j = wheels_jacobian(wheelbase_m)
    q = j @ wheel_covariance(dl, dr, k_m_per_sqrt_m, floor_m) @ j.T
    if turn_fraction:
        q[1, 1] += (turn_fraction * (dr - dl) / wheelbase_m) ** 2
    return q


def motion(state: np.ndarray, u: np.ndarray, c: float = 0.5) -> np.ndarray:
    """Eq. (2): the pose after step u = (ds, dtheta), heading point c; theta wrapped."""
    out = unwrapped_motion(state, u, c)
    out[2] = wrap_angle(out[2])
    return out


def position_measurement(
    state: np.ndarray, lever_m: tuple[float, float] = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """(h, H) of a position sensor (GPS antenna) mounted at ``lever_m`` on the robot."""
    x, y, th = state
    ax, ay = lever_m
    c, s = math.cos(th), math.sin(th)
    h = np.array([x + ax * c - ay * s, y + ax * s + ay * c])
    jac = np.array([[1.0, 0.0, -ax * s - ay * c], [0.0, 1.0, ax * c - ay * s]])
    return h, jac


def heading_measurement(state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h, H) of an absolute heading sensor."""
    return np.array([state[2]]), np.array([[0.0, 0.0, 1.0]])


def gauss_markov(
    b: np.ndarray, dt_s: float, tau_s: float, sigma: float
) -> tuple[np.ndarray, float, float]:
    """(b', a, q): the mean propagation of a first-order Gauss-Markov state over dt, its
    transition factor a = exp(-dt/tau) (the Jacobian) and the process noise variance."""
    a = math.exp(-max(dt_s, 0.0) / tau_s)
    return a * np.asarray(b, float), a, sigma * sigma * (1.0 - a * a)


def biased_position_measurement(
    state: np.ndarray, lever_m: tuple[float, float] = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """(h, H) of the GPS on the state (x, y, theta, b_east, b_north): antenna + bias."""
    h, jac = position_measurement(state[:3], lever_m)
    return h + state[3:5], np.hstack([jac, np.eye(2)])
