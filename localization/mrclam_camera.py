"""Camera model of the MRCLAM robots: range and bearing of a barcode tube (a landmark, or
another robot) as the monocular camera reports them, with the camera's own error states.

The camera ranges by apparent size: a tube of height H at depth Z along the optical axis
is f H / Z pixels tall, so what it reports is the *depth* Z = r cos(psi), not the
Euclidean range r (psi: the bearing from the optical axis). On Dataset 6 the range
error / range is +3.5 % straight ahead and -10 % at the edge of the field of view
(|psi| = 0.55 rad): the -psi^2 / 2 of cos(psi); with the depth model that bearing trend
is gone (docs/algorithms.md). The pixel count is quantised, so the depth error grows as
Z^2 (dZ = Z^2 dh / (f H)).

With the robot's state s (localization/mrclam_motion.py) and the target at m = (mx, my),
numerics.rangebearing gives r = |m - p| and phi0 = atan2(dy, dx) - theta. The camera's
error states: c its range scale error (focal length and tube height calibration), d a
range offset (m), beta its bearing offset (rad: the camera's yaw against the
motion-capture heading), e and q a range scale error that changes across the image (per
rad and rad^2 of bearing: lens distortion, a tilted sensor), and u, v its common range
(relative) and bearing errors, which drift over seconds and which every target seen
shares. Then, with g = 1 + c + u + e psi + q psi^2,

    psi = wrap(phi0 + beta + v)                          (the bearing reported)
    rho = g r cos(psi) + d                               (the range reported, "depth")
    rho = g r + d                                        ("range": the Euclidean model)

Jacobians (checked against finite differences in tests/test_mrclam_ekf.py), with
H_s = d(r, phi0)/d(x, y, theta) and H_m = d(r, phi0)/d(mx, my) of numerics.rangebearing
and rho_psi = d rho / d psi = (e + 2 q psi) r cos(psi) - g r sin(psi) (depth; without
the sine for "range"):

    d rho / d pose = g cos(psi) H_s[0] + rho_psi H_s[1]      (cos(psi) = 1 for "range")
    d rho / dc = d rho / du = r cos psi,  d rho / de = psi r cos psi,
    d rho / dq = psi^2 r cos psi,  d rho / dd = 1,  d rho / d beta = d rho / dv = rho_psi;
    d psi / d pose = H_s[1],  d psi / d beta = d psi / dv = 1;
    the same with H_m for the target. The filter takes g cos(psi) at the measured
    bearing (``psi_m``): then rho does not depend on the heading, and the bearing noise
    moves into the range's (camera_measurement's T).

``target_position`` inverts the model: the target's position from the observer's state
and a measurement (a robot's position fix of another robot), with its Jacobians in the
state and in the measurement.
"""

from __future__ import annotations

import math

import numpy as np

from localization.mrclam_motion import IBETA, IC, ID, IE, IQ, IU, IV, NX
from numerics.angles import wrap_angle
from numerics.rangebearing import range_bearing

MODELS = ("depth", "range")


def camera_measurement(
    s: np.ndarray, mx: float, my: float, model: str = "depth", psi_m: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(z = (rho, psi), H_s = dz/ds (2 x NX), H_m = dz/d(mx, my) (2 x 2), T) of the
    target at (mx, my) seen from the robot state ``s`` (module docstring). The target must
    not sit on the robot (r > 0); callers check the range first.

    With ``psi_m`` (the bearing measured), the range's factor g cos(psi) is taken at
    psi_m instead of the predicted psi, so that the predicted range does not hinge on the
    heading (a heading 0.5 rad off would move it by r (cos 0.1 - cos 0.6), 0.5 m at
    3 m); the bearing's noise then enters the range: the measurement noise is T R T^T
    with T = [[1, -rho_psi], [0, 1]] (T = I without psi_m)."""
    (r, phi0), hs3, hm = range_bearing(s[:3], mx, my)
    c, d, e, q = float(s[IC]) + float(s[IU]), float(s[ID]), float(s[IE]), float(s[IQ])
    psi = wrap_angle(phi0 + float(s[IBETA]) + float(s[IV]))
    at = psi if psi_m is None else float(psi_m)
    g = 1.0 + c + e * at + q * at * at
    cp, sp = (math.cos(at), math.sin(at)) if model == "depth" else (1.0, 0.0)
    rho = g * r * cp + d
    rho_psi = (e + 2.0 * q * at) * r * cp - g * r * sp
    k = rho_psi if psi_m is None else 0.0  # d rho / d psi through the state
    h = np.zeros((2, NX))
    h[0, :3] = g * cp * hs3[0] + k * hs3[1]
    h[0, IC] = h[0, IU] = r * cp
    h[0, ID] = 1.0
    h[0, IBETA] = h[0, IV] = k
    h[0, IE] = at * r * cp
    h[0, IQ] = at * at * r * cp
    h[1, :3] = hs3[1]
    h[1, IBETA] = h[1, IV] = 1.0
    hmo = np.array([g * cp * hm[0] + k * hm[1], hm[1]])
    t = np.eye(2)
    if psi_m is not None:
        t[0, 1] = -rho_psi
    return np.array([rho, psi]), h, hmo, t


def camera_sigmas(
    r: float, sigma_m: float, rel: float, quad: float, bearing: float, lateral_m: float
) -> tuple[float, float]:
    """(range sigma, bearing sigma) at the range ``r``: sqrt(sigma_m^2 + (rel r)^2 +
    (quad r^2)^2) (a floor, a part proportional to the range, the depth quantisation) and
    sqrt(bearing^2 + (lateral_m / r)^2) (a floor and a lateral position error)."""
    sr = math.sqrt(sigma_m * sigma_m + (rel * r) ** 2 + (quad * r * r) ** 2)
    sb = math.sqrt(bearing * bearing + (lateral_m / max(r, 1e-3)) ** 2)
    return sr, sb


def target_position(
    s: np.ndarray, z: np.ndarray, model: str = "depth"
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(p = (x, y), J_s = dp/ds (2 x NX), J_z = dp/dz (2 x 2)) of the target that the
    robot at state ``s`` measured at z = (rho, psi): the inverse of camera_measurement.
    None when the measurement cannot be inverted (range at or below the offset, or the
    depth model with |psi| >= 1.2 rad, outside any camera's field of view)."""
    rho, psi = float(z[0]), float(z[1])
    c, d, e, q = float(s[IC]) + float(s[IU]), float(s[ID]), float(s[IE]), float(s[IQ])
    beta = float(s[IBETA]) + float(s[IV])
    depth = model == "depth"
    g = 1.0 + c + e * psi + q * psi * psi
    if (depth and abs(psi) >= 1.2) or rho - d <= 0.0 or g <= 0.0:
        return None
    cp = math.cos(psi) if depth else 1.0
    r = (rho - d) / (g * cp)
    a = float(s[2]) + psi - beta
    u = np.array([math.cos(a), math.sin(a)])
    un = np.array([-math.sin(a), math.cos(a)])
    p = np.array([float(s[0]), float(s[1])]) + r * u
    js = np.zeros((2, NX))
    js[:, 0] = (1.0, 0.0)
    js[:, 1] = (0.0, 1.0)
    js[:, 2] = r * un
    js[:, IBETA] = js[:, IV] = -r * un
    js[:, IC] = js[:, IU] = -r / g * u
    js[:, IE] = -r * psi / g * u
    js[:, IQ] = -r * psi * psi / g * u
    js[:, ID] = -1.0 / (g * cp) * u
    r_psi = r * ((math.tan(psi) if depth else 0.0) - (e + 2.0 * q * psi) / g)
    jz = np.column_stack([u / (g * cp), r * un + r_psi * u])
    return p, js, jz
