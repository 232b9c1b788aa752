"""Motion model of the MRCLAM robots: commanded velocities (v, w), corrected by a speed
scale and a turn-rate scale that the EKF estimates (localization/mrclam_ekf.py).

State x = (x, y, theta, k, kw, c, d, beta, e, q, u, v): pose, speed scale error k and
turn-rate scale error kw, and the camera states of localization/mrclam_camera.py: range
scale error c, range offset d (m), bearing offset beta (rad), range scale terms across
the image e (per rad of bearing) and q (per rad^2) (random walks: the motion leaves them
unchanged), and the camera's common range and bearing errors u and v (Gauss-Markov:
u' = a_u u, v' = a_v v, a = exp(-dt / tau) with their own tau). The robot moves at v (1 + k) and w (1 + kw); over dt at constant commands
that is the exact arc of numerics.motion (ds = v (1 + k) dt, dtheta = w (1 + kw) dt,
midpoint heading, chord factor). k and kw are first-order Gauss-Markov processes with
correlation time tau: k' = a k, kw' = a kw, a = exp(-dt / tau) (their driving noise is
the filter's).

Why the two states: the drift of the commanded-velocity odometry has a part that
persists for minutes (docs/algorithms.md): the robots of Dataset 6 drive 1-4 % less far
than commanded and turn 4-8 % less (-3.6 to -7.5 % per robot), while a robot driving
straight keeps its heading (heading error p95 0.03 rad over 2-20 s). Landmarks make both
observable, so the filter learns them and carries them through the gaps between
landmarks.

Jacobians (checked against finite differences in tests/test_mrclam_ekf.py), with F3 and
G3 = d pose' / d(ds, dtheta) of numerics.motion:
    d pose' / d pose = F3,  d pose' / dk = G3[:, 0] v dt,  d pose' / dkw = G3[:, 1] w dt,
    d pose' / d(v, w) = G3 diag((1 + k) dt, (1 + kw) dt)  (the white velocity noise).
"""

from __future__ import annotations

import math

import numpy as np

from numerics.motion import motion, motion_jacobians

#: State size: x, y, theta, speed scale error, turn-rate scale error; the camera's range
#: scale error, range offset, bearing offset, range scale terms across the image (linear,
#: quadratic in the bearing), common range and bearing errors.
NX = 12
#: Indices of the non-pose states.
IK, IKW, IC, ID, IBETA, IE, IQ, IU, IV = 3, 4, 5, 6, 7, 8, 9, 10, 11


def velocity_motion(
    s: np.ndarray, v: float, w: float, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s', F = ds'/ds, G = ds'/d(v, w)) of a pose s = (x, y, theta) over dt seconds at
    constant (v, w): the exact arc of numerics.motion."""
    u = np.array([v * dt, w * dt])
    f, g = motion_jacobians(s, u, 0.5, True)
    return motion(s, u, 0.5, True), f, g * dt


def biased_motion(
    x: np.ndarray,
    v: float,
    w: float,
    dt: float,
    tau: float,
    tau_common: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x', F = dx'/dx (NX x NX), G = dx'/d(v, w) (NX x 2)) of the state x over dt
    seconds at the commands (v, w); tau: the correlation time of k and kw, tau_common of
    u and v (0: constant); see the module docstring."""
    k, kw = float(x[IK]), float(x[IKW])
    u = np.array([v * (1.0 + k) * dt, w * (1.0 + kw) * dt])
    f3, g3 = motion_jacobians(x[:3], u, 0.5, True)
    a = math.exp(-dt / tau) if tau > 0.0 else 1.0
    # numerics.motion's F holds the step: F[0, 2] = -ds c sin(phi), F[1, 2] = ds c cos(phi),
    # so the new pose is read off it (tests check it against numerics.motion.motion).
    out = np.array(x, dtype=float)
    out[:5] = (x[0] + f3[1, 2], x[1] - f3[0, 2], x[2] + u[1], a * k, a * kw)
    f = np.eye(NX)
    f[:3, :3] = f3
    f[:3, 3] = g3[:, 0] * (v * dt)
    f[:3, 4] = g3[:, 1] * (w * dt)
    f[3, 3] = f[4, 4] = a
    for i, tc in zip((IU, IV), tau_common, strict=True):
        f[i, i] = math.exp(-dt / tc) if tc > 0.0 else 1.0
        out[i] = f[i, i] * x[i]
    g = np.zeros((NX, 2))
    g[:3, 0] = g3[:, 0] * ((1.0 + k) * dt)
    g[:3, 1] = g3[:, 1] * ((1.0 + kw) * dt)
    return out, f, g
