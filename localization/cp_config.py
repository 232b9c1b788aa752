"""Settings of interval constraint-propagation localization (ekf-vs-cp.txt eq. (5)):
the guaranteed error bounds of the odometry model eq. (1)-(2), the GPS and the gyro
(bounds, not sigmas), how far a stamp difference may move a box, and the solver's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class CPConfig:
    """Error bounds (guaranteed, not sigmas) and solver settings."""

    wheelbase_m: float = 0.33
    wheelbase_bound_m: float = 0.0
    wheel_abs_bound_m: float = 0.0005  # per wheel per step
    wheel_rel_bound: float = 0.01  # fraction of the wheel's displacement per step
    gps_bound_m: float = 2.0  # per axis
    gyro_bound_rad: float = math.radians(1.0)
    gyro_drift_bound_radps: float = 0.0  # growth of the gyro bound with time
    gyro_offset_rad: float = 0.0  # map heading = gyro angle + offset
    window: int = 60  # past steps kept (0 = recursive filter)
    gps_outliers: int = 0  # q of the relaxed intersection over the window
    speed_bound_mps: float = 3.0  # to bridge time-stamp differences (own and peers)
    yaw_rate_bound_radps: float = 3.0
    kappa: float = 0.5
    chord: bool = True
    hc4_odometry: bool = False  # also contract headings from the positions (eq. (2) backward)
    iterations: int = 3
    tol: float = 1e-3
    min_gps_mode: int = 2
