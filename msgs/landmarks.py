"""Messages of landmark (feature) SLAM: vehicle controls, range-bearing landmark scans and
the estimated landmark map (slam-ekf.txt §4: u = [v, steering], z = [r, phi]).

Bearings follow the sensor's own convention, stated in ``bearing_zero`` of the scan:
"x" means 0 rad = straight ahead (counter-clockwise positive, wrapped to (-pi, pi]);
"y" means the paper's laser convention, 0 rad along the sensor's -y axis so that
pi/2 = straight ahead (Victoria Park detections: 0..pi).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class VehicleControl:
    """Dead-reckoning input of a car-like vehicle: encoder speed (m/s) and steering (rad).

    speed_mps is as measured (e.g. at the rear left wheel for Victoria Park); the SLAM
    vehicle model converts it to the rear axle centre.
    """

    stamp_ns: int
    speed_mps: float
    steering_rad: float


@dataclass(frozen=True, slots=True)
class LandmarkScan:
    """Landmarks detected in one sensor scan: range (m), bearing (rad), size (m).

    The three tuples have the same length (possibly zero). diameters_m may hold 0.0
    where the detector gives no size.
    """

    stamp_ns: int
    ranges_m: tuple[float, ...]
    bearings_rad: tuple[float, ...]
    diameters_m: tuple[float, ...] = ()
    bearing_zero: str = "x"
    sensor: str = "laser"


@dataclass(frozen=True, slots=True)
class LandmarkMap:
    """A landmark map in ``frame``: the confirmed landmarks of an EKF-SLAM map, or a data
    set's surveyed map of known landmarks.

    For landmark i: ids[i], position (xs[i], ys[i]) in metres and its marginal 2x2
    covariance (cov_xx[i], cov_xy[i], cov_yy[i]) in m^2.
    """

    stamp_ns: int
    ids: tuple[int, ...]
    xs: tuple[float, ...]
    ys: tuple[float, ...]
    cov_xx: tuple[float, ...]
    cov_xy: tuple[float, ...]
    cov_yy: tuple[float, ...]
    frame: str = "map"
