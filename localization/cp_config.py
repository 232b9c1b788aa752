"""Settings of interval constraint-propagation localization (ekf-vs-cp.txt eq. (5)):
the guaranteed error bounds of the odometry model eq. (1)-(2), the GPS and the gyro
(bounds, not sigmas), how far a stamp difference may move a box, and the solver's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: What a range-bearing sensor's range measures (RangeBearingCPConfig.range_model).
RANGE_MODELS = ("depth", "range")


def poly(c: tuple[float, float, float], r: float) -> float:
    """c0 + c1 r + c2 r^2."""
    return c[0] + r * (c[1] + r * c[2])


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
    iterations: int = 2
    tol: float = 1e-3
    min_gps_mode: int = 2


@dataclass(frozen=True)
class RangeBearingCPConfig:
    """Guaranteed bounds and solver settings of the real-robot CP localizer
    (``localization.cp_rb``): velocity odometry, range-bearing to known landmarks and to
    peers. Bounds, not sigmas.

    How the defaults were derived (docs/algorithms.md, "CP on real robots", has the
    figures; ``bench/mrclam_errors.py DIR`` prints them for any MRCLAM run): each bound is
    a robot or sensor property read off Dataset 6's motion-capture truth over all five
    robots, at or above the 99.9th percentile of the error and rounded outward; nothing
    was tuned on the localizer's score. Errors beyond a bound are the q-relaxation's job
    (``outliers``), and the motion model is set at the largest error seen (it cannot be
    voted out).
    """

    # -- velocity odometry (localization.velocity_odometry) --
    #: Commands act this much after their stamp (README: truth trails by 0.16-0.20 s).
    command_lag_s: float = 0.18
    #: A command older than this is no longer trusted (largest odometry gap seen: 1.03 s).
    max_hold_s: float = 1.1
    #: Heading transient a: |E(t1) - E(t0)| <= a + b dt + b_m int|v| + r int|w| over
    #: every pair of instants up to 10 s apart, E the integrated heading's error (b, b_m,
    #: r below): a is exceeded by 5e-5 of the 20 million pairs of 5 x 888 s (0.116 rad;
    #: 0.111 over pairs up to 60 s apart; the largest residual, 0.157, at motion-capture
    #: glitches). A robot that drives straight keeps its heading: the drift is mostly per
    #: metre driven, not per second (with b = 0.03 rad/s and no b_m, a = 0.10).
    heading_transient_rad: float = 0.12
    heading_drift_radps: float = 0.005  # b
    heading_drift_per_m: float = 0.1  # b_m, rad per metre of commanded path
    heading_turn_rel: float = 0.3  # r, fraction of the commanded turn
    #: The same pair condition with a smaller turn fraction r2 (the slope of the
    #: residual's tail over turns of 1-4 rad: the turn rate's scale errors of 3-8 % with
    #: a margin) and the transient a2 it then needs: exceeded by 5e-5 of the 30 million
    #: pairs of instants up to 60 s apart (0.171 rad). Long turns: a + r S against
    #: a2 + r2 S, the smaller holds (velocity_odometry: ``dw``).
    heading_turn_rel_long: float = 0.12
    heading_transient_long_rad: float = 0.175
    yaw_rate_cap_radps: float = 0.7  # fastest turn seen: 0.61 rad/s
    #: Path length L in [(1 - lo) S - p, (1 + hi) S + p], p = path_abs + path_drift dt.
    speed_rel_hi: float = 0.2
    speed_rel_lo: float = 1.0  # robots stall while commanded to move
    path_abs_m: float = 0.005
    path_drift_mps: float = 0.01
    #: Per-axis slack (pushes, sideways motion): slack_abs + slack_drift dt.
    slack_abs_m: float = 0.005
    slack_drift_mps: float = 0.005
    speed_cap_mps: float = 0.1  # fastest seen: 0.084 m/s
    # -- range-bearing (localization.range_bearing) --
    #: What the camera's range is: "depth" (it ranges a tube by its apparent size, so it
    #: reports the depth r cos(psi) along the optical axis, psi the bearing) or "range"
    #: (the Euclidean range r). With "depth" the bounds below hold r cos(psi_m) (psi_m the
    #: bearing measured) and the true range is in [lo, hi] / cos(psi_m).
    range_model: str = "depth"
    #: The true depth d of a sighting measured at rho (range_model "depth"; the range
    #: itself with "range") is within [rho + lo(rho), rho + hi(rho)], lo and hi quadratics
    #: c0 + c1 rho + c2 rho^2 (metres; coefficients (c0, c1, c2)). Landmarks: the 0.05th
    #: and 99.95th percentile lines of d - rho on (1, rho, rho^2) by linear quantile
    #: regression over the landmark sightings (misreads left out), coefficients rounded
    #: outward (``bench/mrclam_errors.py`` derives them for any run): the camera's
    #: depth error is an offset and a scale (the measured rho is 2-7 % long, plus
    #: 2-4 cm) and a quantisation that grows as rho^2 (the EKF's noise model has the same
    #: shape), so a line (the previous bound, [(1 - 0.085) rho - 0.02, (1 + 0.01) rho
    #: + 0.02]) is too wide at 2-4 m where most sightings are (0.15 / 0.21 / 0.29 m wide
    #: at 2 / 3 / 4 m, against 0.23 / 0.33 / 0.42).
    range_lo_poly: tuple[float, float, float] = (-0.1302, -0.0045, -0.0089)
    range_hi_poly: tuple[float, float, float] = (-0.0015, -0.0245, 0.0066)
    #: Robots seen (their tubes read farther; the tails of their range errors are
    #: other robots' barcodes misread, too few clean ones for a quadratic): true depth /
    #: measured in [0.891, 0.985] with +- 2 cm, the 0.05th and 99.95th percentiles
    #: (misreads left out); as a range [0.909, 1.151].
    robot_range_lo_poly: tuple[float, float, float] = (-0.02, -0.115, 0.0)
    robot_range_hi_poly: tuple[float, float, float] = (0.02, -0.01, 0.0)
    #: Bearing error = a part common to every bearing of one frame (the camera's own
    #: heading error against the motion capture's, partly its timing) + a part per bearing, a
    #: floor plus a lateral error of the tube's image over the range (the EKF's noise
    #: model has the same shape: 0.0095^2 + (0.024 / r)^2). Over 10530 frames (19268
    #: landmark and robot bearings) a common part within 0.06 rad leaves every bearing
    #: within 0.015 + 0.02 / r rad of it (0.028 at 1.5 m, 0.019 at 5 m) but for 18
    #: (0.093 %, of which 14 gross outliers: barcodes misread); with a flat per-bearing
    #: bound, 0.05 and 0.03 (0.099 %).
    bearing_common_rad: float = 0.06
    bearing_rad: float = 0.015
    bearing_lateral_m: float = 0.02
    #: Landmarks' surveyed positions +- this many of their standard deviations.
    landmark_sigmas: float = 5.0
    #: A peer's published box is widened by these times its age.
    peer_speed_mps: float = 0.1
    peer_yaw_rate_radps: float = 0.7
    #: A peer's box is not used for this long after the peer weakened its guarantee
    #: (relaxed, reinit, lost): two windows, for its window to hold only fresh data.
    peer_quarantine_s: float = 5.0
    #: Use a peer's pieces (heading slices, each with its own position box; the peer is
    #: in one of them) rather than their hull: the observation is contracted with each
    #: and the hull of the results kept, so a peer's heading stays coupled with its
    #: position (cp_rb_solve, a union's columns).
    peer_pieces: bool = True
    # -- solver (localization.cp_rb_solve) --
    #: q: observations of the window that may break their bounds.
    outliers: int = 1
    #: On an empty window, up to this many more are voted out (the prior kept) before
    #: the prior is dropped (localization.cp_rb, "graceful failure").
    max_extra_outliers: int = 3
    window_s: float = 2.5
    #: Solve at most this often (s; 0: at every camera frame, about every 0.23 s).
    #: Frames in between join the window and are used at the next solve; boxes are
    #: predicted from the last solve. 0.3 s solves every other frame: 1.8x fewer solves
    #: for boxes about 10 % larger (docs/benchmarks.md).
    solve_period_s: float = 0.3
    max_states: int = 12
    iterations: int = 2
    tol: float = 0.01
    #: The newest heading is cut into pieces this wide (at most max_pieces), or, when it
    #: is unknown, into heading_sectors sectors of the circle (localization.cp_rb_solve).
    heading_piece_rad: float = 0.1
    max_pieces: int = 5
    heading_sectors: int = 24

    def __post_init__(self) -> None:
        for lo, hi in (
            (self.range_lo_poly, self.range_hi_poly),
            (self.robot_range_lo_poly, self.robot_range_hi_poly),
        ):
            if len(lo) != 3 or len(hi) != 3 or not all(map(math.isfinite, (*lo, *hi))):
                raise ValueError("range polynomials: three finite coefficients (c0, c1, c2)")
            if any(poly(hi, r) < poly(lo, r) for r in (0.0, 0.5, 1, 2, 4, 8, 16, 32)):
                raise ValueError(f"range polynomials: hi below lo somewhere ({lo}, {hi})")
        if self.range_model not in RANGE_MODELS:
            raise ValueError(f"range_model must be one of {RANGE_MODELS}, got {self.range_model!r}")
        if self.outliers < 0 or self.window_s <= 0 or self.max_states < 2 or self.iterations < 1:
            raise ValueError(
                "RangeBearingCPConfig: outliers >= 0, window_s > 0, max_states >= 2 and "
                f"iterations >= 1 are required (got {self})"
            )
