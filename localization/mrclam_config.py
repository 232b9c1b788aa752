"""Settings of the MRCLAM EKF (localization/mrclam_ekf.py, mrclam_filter.py,
mrclam_service.py). Every default is derived in docs/algorithms.md ("EKF on the MRCLAM
robots") from the data README's error percentiles, the same statistics of the errors
over longer windows and after the camera model, and physical reasoning (sigma = p95 /
1.96); none was fitted to a score."""

from __future__ import annotations

import math
from dataclasses import dataclass

from localization.mrclam_camera import MODELS

COOPERATION = ("joint", "split_ci", "ci", "none")


@dataclass(frozen=True)
class MrclamEkfConfig:
    """Noise model and filter settings (1-sigma)."""

    #: Commands act this much later than stamped (README: truth trails by 0.16-0.20 s).
    command_lag_s: float = 0.18
    #: Window over which the white velocity sigmas below are defined (their intensity
    #: is sigma^2 * window); derived from the drift over 5-40 s windows.
    noise_window_s: float = 10.0
    #: sigma of the window-averaged forward velocity: v0 + kv |v| (m/s).
    v_sigma_mps: float = 0.0037
    v_sigma_rel: float = 0.028
    #: Heading noise: variance (w_noise_time + w_noise_turn |w|) dt over a step of dt at
    #: the commanded turn rate w: rad^2/s, and rad^2 per rad turned (the heading of a
    #: robot driving straight does not drift; a turning one's error grows with the
    #: angle turned).
    w_noise_time: float = 3e-5
    w_noise_turn: float = 0.01
    #: Stationary sigma of the speed scale error k and of the turn-rate scale error kw,
    #: and their correlation time (Gauss-Markov states; 0 sigmas switch them off).
    speed_scale_sigma: float = 0.031
    turn_scale_sigma: float = 0.06
    bias_tau_s: float = 120.0
    #: Camera: "depth" (the range reported is the depth along the optical axis) or
    #: "range" (Euclidean range), localization/mrclam_camera.py.
    camera_model: str = "depth"
    #: Prior sigmas of the camera's range scale error c, range offset d (m), bearing
    #: offset beta (rad) and range scale terms across the image e (per rad) and q (per
    #: rad^2), all starting at 0 (0 switches a state off); they random-walk so that
    #: their variance grows by the prior's over ``camera_drift_s``.
    camera_scale_sigma: float = 0.05
    camera_offset_sigma_m: float = 0.05
    camera_bearing_sigma_rad: float = 0.01
    camera_slope_sigma: float = 0.03
    camera_distortion_sigma: float = 0.05
    camera_drift_s: float = 3600.0
    #: The camera's errors common to every target it sees (range relative, bearing rad):
    #: Gauss-Markov states u, v with these stationary sigmas and correlation times.
    camera_common_sigma: tuple[float, float] = (0.0027, 0.0067)
    camera_common_tau_s: tuple[float, float] = (15.0, 14.0)
    #: "measured": the range's factor g cos(psi) at the measured bearing (the range
    #: predicted does not hinge on the heading); "predicted": at the predicted bearing.
    range_factor_bearing: str = "measured"
    #: Robots' barcode tubes read this much farther than the landmarks' (m).
    robot_target_offset_m: float = 0.025
    #: Range sigma^2 = range_sigma_m^2 + (range_sigma_rel r)^2 + (range_sigma_quad r^2)^2;
    #: bearing sigma^2 = bearing_sigma_rad^2 + (bearing_sigma_lateral_m / r)^2, r the
    #: predicted range (so that a wrong range cannot widen its own gate): the errors
    #: left by the camera model, of which the common part (above) is in the state.
    range_sigma_m: float = 0.017
    range_sigma_rel: float = 0.0
    range_sigma_quad: float = 0.0014
    bearing_sigma_rad: float = 0.0095
    bearing_sigma_lateral_m: float = 0.024
    #: Of those variances (range, bearing): the white part, and the part correlated in
    #: time for one target (the rest is the common part): the latter is inflated by
    #: the AR(1) factor of the time since the target's previous measurement used, with
    #: the integral time scales error_correlation_s of its autocorrelation.
    error_white_fraction: tuple[float, float] = (0.55, 0.46)
    error_target_fraction: tuple[float, float] = (0.31, 0.25)
    error_correlation_s: tuple[float, float] = (15.0, 11.0)
    #: "subject": the correlated part is per target; "robot": one process per robot.
    correlation_scope: str = "robot"
    #: Measurements of one robot at most frame_gap_s after the first of a camera frame
    #: are that frame. Their white errors are correlated across targets at zero lag
    #: (rho, range and bearing): the k-th measurement used of a frame has its white
    #: variance multiplied by 1 / (k / (1 + (k - 1) rho) - (k - 1) / (1 + (k - 2) rho)),
    #: so that k of them carry the information of the mean of k equicorrelated ones.
    frame_gap_s: float = 0.01
    frame_correlation: tuple[float, float] = (0.21, 0.58)
    #: Chi-square gate probability (2 dof) for landmark and robot measurements.
    gate_probability: float = 0.999
    #: Robot-to-robot measurements: "joint" (one filter over every robot, the
    #: cross-covariances tracked exactly: the centralized equivalent), "split_ci" (one
    #: filter per robot fed the others' published estimates; split covariance
    #: intersection: the camera noise independent, both estimates of unknown
    #: correlation), "ci" (covariance intersection, everything of unknown correlation),
    #: "none" (landmarks only).
    cooperation: str = "joint"
    #: split_ci / ci: "both" also updates the observed robot (from the observer's
    #: position fix of it, made from the observer's prior); "observer" only the observer.
    peer_update: str = "both"
    #: Covariance intersection weight: minimise "det" or "trace" of the pose block.
    ci_criterion: str = "det"
    #: A peer's published estimate ``age`` seconds old gets (peer_speed_mps age)^2 more
    #: variance in x and y (the iRobot Create's top speed).
    peer_speed_mps: float = 0.5
    #: The track has a row every output_period_s from the robot's start (on_grid), and
    #: one after every measurement update of the robot.
    output_period_s: float = 0.05
    #: Initial sigma (x, y, theta) around the initial pose.
    init_sigma: tuple[float, float, float] = (0.05, 0.05, 0.05)

    def __post_init__(self) -> None:
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        choices = {
            "ci_criterion": ("det", "trace"),
            "correlation_scope": ("robot", "subject"),
            "peer_update": ("observer", "both"),
            "cooperation": COOPERATION,
            "camera_model": MODELS,
            "range_factor_bearing": ("measured", "predicted"),
        }
        for name, allowed in choices.items():
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, got {getattr(self, name)!r}")
        for name in ("output_period_s", "noise_window_s", "camera_drift_s"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")

    @property
    def gate(self) -> float:
        """chi2 quantile with 2 degrees of freedom: -2 ln(1 - p)."""
        return -2.0 * math.log1p(-self.gate_probability)
