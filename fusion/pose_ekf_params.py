"""Parameters of the pose EKF (fusion.pose_ekf), and the GPS fix -> (z, R) conversion.

GPS bias defaults (``gps_bias_states``, on by default): a standalone consumer receiver
(u-blox M8/M10 class, open sky) is specified at about 2.5 m CEP horizontal, i.e. a
per-axis sigma of about 2.1 m, most of it the slowly wandering part (satellite geometry,
ionosphere, multipath) that decorrelates over minutes; the fix-to-fix noise is a few
decimetres. Hence sigma_b = 2.0 m, tau = 300 s, and the white part of a fix taken as
``gps_white_fraction`` = 0.3 of the sigma the receiver claims (GST, or HDOP x UERE), the
claimed sigma covering both parts. These are datasheet-order figures, not the simulated
receiver's (fakes/world/gps_model.py: 1.5 m, 120 s, white 0.5 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fusion.ekf_update import chi2_gate
from msgs import GpsFix

DEG = math.pi / 180.0


@dataclass(frozen=True)
class PoseEkfParams:
    """Noise, gating and timeout parameters of the pose EKF (SI units)."""

    wheelbase_m: float = 0.33
    wheel_noise_m_per_sqrt_m: float = 0.005
    wheel_noise_floor_m: float = 1e-4
    turn_noise_fraction: float = 0.1
    heading_point: float = 0.5
    gyro_gamma: float = 0.02
    gyro_arw_rad_per_sqrt_s: float = 0.015 * DEG
    gyro_bias_sigma_radps: float = 0.005 * DEG
    gyro_timeout_s: float = 0.5
    gyro_max_lag_s: float = 0.05
    gyro_max_defer_s: float = 2.0
    odometry_timeout_s: float = 0.5
    learn_bias_at_rest: bool = True
    bias_window_s: float = 30.0
    bias_min_rest_s: float = 0.5
    gps_uere_m: float = 4.0
    gps_min_sigma_m: float = 0.02
    gps_timeout_s: float = 3.0
    gps_max_lag_s: float = 0.25
    gps_lever_m: tuple[float, float] = (0.0, 0.0)
    gps_error_correlation_s: float = 0.0
    gps_bias_states: bool = True
    gps_bias_sigma_m: float = 2.0
    gps_bias_tau_s: float = 300.0
    gps_white_fraction: float = 0.3
    init_from_gps: bool = True
    gate_probability: float | None = 0.99
    initial_sigma_xy_m: float = 0.01
    initial_sigma_theta_rad: float = 0.1 * DEG
    frame: str = "map"
    robot: str = "r1"

    def __post_init__(self) -> None:
        for name in ("wheelbase_m", "gps_uere_m", "gps_timeout_s", "gyro_timeout_s",
                     "odometry_timeout_s"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"PoseEkfParams.{name} must be finite and > 0, got {v!r}")
        for name in ("wheel_noise_m_per_sqrt_m", "wheel_noise_floor_m", "turn_noise_fraction",
                     "gyro_gamma", "gyro_arw_rad_per_sqrt_s", "gyro_bias_sigma_radps",
                     "gps_min_sigma_m", "gps_max_lag_s", "gyro_max_lag_s", "gyro_max_defer_s", "gps_error_correlation_s",
                     "initial_sigma_xy_m", "initial_sigma_theta_rad", "bias_window_s",
                     "gps_bias_sigma_m",
                     "bias_min_rest_s"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"PoseEkfParams.{name} must be finite and >= 0, got {v!r}")
        if not (math.isfinite(self.gps_bias_tau_s) and self.gps_bias_tau_s > 0.0):
            raise ValueError(
                f"PoseEkfParams.gps_bias_tau_s must be > 0, got {self.gps_bias_tau_s!r}"
            )
        if not 0.0 < self.gps_white_fraction <= 1.0:
            raise ValueError(
                f"PoseEkfParams.gps_white_fraction must be in (0, 1], got {self.gps_white_fraction!r}"
            )
        g = self.gate_probability
        if g is not None and not 0.0 < g < 1.0:
            raise ValueError(f"PoseEkfParams.gate_probability must be in (0, 1) or None, got {g!r}")

    def gate(self, dof: int) -> float:
        """Chi-square gate on the NIS for a measurement of ``dof`` dimensions (inf: off)."""
        return chi2_gate(self.gate_probability, dof)

    @property
    def n_states(self) -> int:
        return 5 if self.gps_bias_states else 3


def gps_fix_measurement(msg: GpsFix, p: PoseEkfParams) -> tuple[np.ndarray, np.ndarray] | None:
    """(z, R) of a fix in local metres, or None when it has no usable position."""
    if msg.mode < 2 or msg.quality == 0 or msg.east_m is None or msg.north_m is None:
        return None
    if msg.std_lat_m is not None and msg.std_lon_m is not None:
        se, sn = msg.std_lon_m, msg.std_lat_m
    elif msg.hdop is not None:
        se = sn = msg.hdop * p.gps_uere_m / math.sqrt(2.0)
    else:
        return None
    se, sn = max(se, p.gps_min_sigma_m), max(sn, p.gps_min_sigma_m)
    if p.gps_bias_states:  # the slowly wandering part is a state: R is the white part
        se, sn = se * p.gps_white_fraction, sn * p.gps_white_fraction
        se, sn = max(se, p.gps_min_sigma_m), max(sn, p.gps_min_sigma_m)
    z = np.array([msg.east_m, msg.north_m], dtype=float)
    r = np.diag([se * se, sn * sn])
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(r))):
        return None
    return z, r
