"""Range and bearing of a point seen from a pose, and their Jacobians.

A sensor at pose s = (x, y, theta) (0 rad straight ahead, counter-clockwise positive)
sees the point m = (mx, my) at

    r   = sqrt(dx^2 + dy^2),        dx = mx - x,  dy = my - y,  q = r^2
    phi = wrap(atan2(dy, dx) - theta)

with the Jacobians (checked against finite differences in tests/test_mrclam_ekf.py)

    H_s = d(r, phi)/d(x, y, theta) = [[-dx/r, -dy/r,  0],
                                      [ dy/q, -dx/q, -1]]
    H_m = d(r, phi)/d(mx, my)      = [[ dx/r,  dy/r],
                                      [-dy/q,  dx/q]]

A landmark is m with a known position (H_m carries its position covariance into R);
another robot is m = (x_j, y_j) of its pose, so d(r, phi)/d(s_j) = [H_m, 0].
(mapping/slam/models.observe is the same model, vectorised, with a bearing offset.)
"""

from __future__ import annotations

import math

import numpy as np

from numerics.angles import wrap_angle


def range_bearing(s: np.ndarray, mx: float, my: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(z = (r, phi), H_s (2x3), H_m (2x2)) of the point (mx, my) seen from pose ``s``.

    The point must not sit on the pose (r > 0); callers check the range first.
    """
    dx = mx - float(s[0])
    dy = my - float(s[1])
    q = dx * dx + dy * dy
    r = math.sqrt(q)
    phi = wrap_angle(math.atan2(dy, dx) - float(s[2]))
    hm = np.array([[dx / r, dy / r], [-dy / q, dx / q]])
    hs = np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])
    return np.array([r, phi]), hs, hm
