"""Motion model of the MRCLAM robots: commanded velocities (v, w), corrected by a speed
scale and a turn-rate bias that the EKF estimates (localization/mrclam_ekf.py).

State x = (x, y, theta, k, b): pose, speed scale error k and turn-rate bias b (rad/s).
The robot moves at v (1 + k) and w + b; over dt at constant commands that is the exact
arc of numerics.motion (ds = v (1 + k) dt, dtheta = (w + b) dt, midpoint heading, chord
factor). k and b are first-order Gauss-Markov processes with correlation time tau:
k' = a k, b' = a b, a = exp(-dt / tau) (their driving noise is the filter's).

Why the two states: the drift of the commanded-velocity odometry grows faster than a
random walk (its intensity doubles from 5 s to 40 s windows, docs/algorithms.md), i.e.
part of it is a bias that persists for minutes; the robots of Dataset 6 drive 1-4 % less
far than commanded and turn 4-7 % less, with a mean turn-rate error of -1 to -5 mrad/s
that holds over both halves of the run. Landmarks make both observable, so the filter
learns them and carries them through the gaps between landmarks.

Jacobians (checked against finite differences in tests/test_mrclam_ekf.py), with F3 and
G3 = d pose' / d(ds, dtheta) of numerics.motion:
    d pose' / d pose = F3,  d pose' / dk = G3[:, 0] v dt,  d pose' / db = G3[:, 1] dt,
    d pose' / d(v, w) = G3 diag((1 + k) dt, dt)  (the white velocity noise).
"""

from __future__ import annotations

import math

import numpy as np

from numerics.motion import motion, motion_jacobians

#: State size: x, y, theta, speed scale error, turn-rate bias.
NX = 5


def velocity_motion(
    s: np.ndarray, v: float, w: float, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s', F = ds'/ds, G = ds'/d(v, w)) of a pose s = (x, y, theta) over dt seconds at
    constant (v, w): the exact arc of numerics.motion."""
    u = np.array([v * dt, w * dt])
    f, g = motion_jacobians(s, u, 0.5, True)
    return motion(s, u, 0.5, True), f, g * dt


def biased_motion(
    x: np.ndarray, v: float, w: float, dt: float, tau: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x', F = dx'/dx (5x5), G = dx'/d(v, w) (5x2)) of the state x over dt seconds at
    the commands (v, w); see the module docstring."""
    k, b = float(x[3]), float(x[4])
    u = np.array([v * (1.0 + k) * dt, (w + b) * dt])
    f3, g3 = motion_jacobians(x[:3], u, 0.5, True)
    a = math.exp(-dt / tau) if tau > 0.0 else 1.0
    # numerics.motion's F holds the step: F[0, 2] = -ds c sin(phi), F[1, 2] = ds c cos(phi),
    # so the new pose is read off it (tests check it against numerics.motion.motion).
    out = np.array([x[0] + f3[1, 2], x[1] - f3[0, 2], x[2] + u[1], a * k, a * b])
    f = np.zeros((NX, NX))
    f[:3, :3] = f3
    f[:3, 3] = g3[:, 0] * (v * dt)
    f[:3, 4] = g3[:, 1] * dt
    f[3, 3] = f[4, 4] = a
    g = np.zeros((NX, 2))
    g[:3, 0] = g3[:, 0] * ((1.0 + k) * dt)
    g[:3, 1] = g3[:, 1] * dt
    return out, f, g
