"""Message-level EKF-SLAM service: what the daemon, the replay and the benches call.

``LandmarkSlam(config)`` owns an :class:`~mapping.slam.ekf.EkfSlam` and the data
association (gating + NN or JCBB, new-landmark threshold, tentative list):

- ``on_control(VehicleControl) -> PoseEstimate``: car dead reckoning. The previous
  control is held over the interval up to this stamp (zero-order hold) and the filter
  predicts with the Ackermann model (slam-ekf.txt §4.1, the discrete f1..f3).
- ``on_odometry(RobotOdometry) -> PoseEstimate``: differential-drive odometry, its pose
  increments feed the unicycle model (the simulated Pioneer).
- ``on_scan(LandmarkScan) -> tuple[PoseEstimate, LandmarkMap]``: predicts up to the scan
  stamp (car mode), associates, updates (§4.2.3), confirms candidates and augments the
  state (§4.2.4). Bearings are read in the scan's own convention (``bearing_zero``: "y"
  is the paper's +pi/2 laser, "x" is 0 rad ahead).
- ``pose_estimate(stamp_ns)``, ``landmark_map(stamp_ns)``, ``stats`` (counters).

Pure: no clocks, the stamps of the messages are the only time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.slam.association import (
    CHI2_2DOF_99,
    CHI2_2DOF_999,
    TentativeLandmarks,
    classify_unmatched,
    mahalanobis_matrix,
    nearest_neighbour,
)
from mapping.slam.ekf import EkfSlam
from mapping.slam.jcbb import jcbb
from mapping.slam.models import (
    HALF_PI,
    AckermannGeometry,
    AckermannModel,
    UnicycleModel,
    inverse_observe,
)
from msgs.estimates import PoseEstimate
from msgs.geometry import Pose2D
from msgs.landmarks import LandmarkMap, LandmarkScan, VehicleControl
from msgs.robot import RobotOdometry
from numerics.angles import wrap

BEARING_OFFSETS = {"y": HALF_PI, "x": 0.0}


@dataclass(frozen=True)
class SlamConfig:
    """Parameters of the EKF-SLAM service (SI units; sigmas are 1-sigma).

    vehicle: "ackermann" (u = encoder speed, steering; geometry below) or "unicycle"
    (odometry increments). Control noise: ackermann ``sigma_speed_mps`` and
    ``sigma_steer_rad`` per ``nominal_dt_s`` step (scaled for other step lengths as white
    noise); unicycle ``sigma_d_per_sqrt_m`` (distance) and ``sigma_theta_per_sqrt_m``,
    ``sigma_theta_per_sqrt_rad`` (heading). Observations: ``sigma_range_m``,
    ``sigma_bearing_rad``, used between ``min_range_m`` and ``max_range_m``.
    Association: ``association`` "nn" or "jcbb", individual gate ``gate_chi2``, an
    unmatched observation farther than ``new_chi2`` from all landmarks is a candidate,
    confirmed after ``confirm_after`` sightings (``tentative_max_age_scans`` to expire).
    """

    vehicle: str = "ackermann"
    geometry: AckermannGeometry = field(default_factory=AckermannGeometry)
    sigma_speed_mps: float = 0.5
    sigma_steer_rad: float = math.radians(3.0)
    nominal_dt_s: float = 0.025
    sigma_d_per_sqrt_m: float = 0.01
    sigma_theta_per_sqrt_m: float = 0.01
    sigma_theta_per_sqrt_rad: float = 0.02
    sigma_range_m: float = 0.5
    sigma_bearing_rad: float = math.radians(1.0)
    min_range_m: float = 0.5
    max_range_m: float = 40.0
    association: str = "nn"
    gate_chi2: float = CHI2_2DOF_99
    new_chi2: float = CHI2_2DOF_999
    confirm_after: int = 3
    tentative_max_age_scans: int = 20
    jcbb_max_nodes: int = 3000
    initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    initial_sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_dt_s: float = 1.0

    def __post_init__(self) -> None:
        if self.vehicle not in ("ackermann", "unicycle"):
            raise ValueError(f"vehicle must be 'ackermann' or 'unicycle', got {self.vehicle!r}")
        if self.association not in ("nn", "jcbb"):
            raise ValueError(f"association must be 'nn' or 'jcbb', got {self.association!r}")
        if not self.new_chi2 >= self.gate_chi2:
            raise ValueError("new_chi2 must be >= gate_chi2")
        if self.confirm_after < 1:
            raise ValueError("confirm_after must be >= 1")


@dataclass
class SlamStats:
    """Counters of what the service did (for diagnostics and benches)."""

    controls: int = 0
    scans: int = 0
    observations: int = 0
    matched: int = 0
    new_candidates: int = 0
    ambiguous: int = 0
    out_of_range: int = 0
    promoted: int = 0
    skipped: int = 0


class LandmarkSlam:
    """EKF-SLAM fed messages; see the module docstring for the API."""

    def __init__(self, config: SlamConfig | None = None) -> None:
        self.config = cfg = config or SlamConfig()
        model = AckermannModel(cfg.geometry) if cfg.vehicle == "ackermann" else UnicycleModel()
        self.ekf = EkfSlam(
            model,
            x0=np.array(cfg.initial_pose, float),
            p0=np.diag(np.square(cfg.initial_sigma)),
            r=np.diag([cfg.sigma_range_m**2, cfg.sigma_bearing_rad**2]),
            bearing_offset=HALF_PI,
        )
        self.tentative = TentativeLandmarks(
            confirm_after=cfg.confirm_after,
            max_age_scans=cfg.tentative_max_age_scans,
            gate=cfg.gate_chi2,
        )
        self.stats = SlamStats()
        self._t_ns: int | None = None
        self._u = (0.0, 0.0)
        self._q_nominal = np.diag([cfg.sigma_speed_mps**2, cfg.sigma_steer_rad**2])
        self._q = (0.0, self._q_nominal)  # (dt, Q of a step of dt): dt rarely changes
        self._last_odom: Pose2D | None = None

    # ------------------------------------------------------------ prediction
    def _advance(self, t_ns: int) -> None:
        """Predict with the held control from the last stamp up to ``t_ns`` (car mode)."""
        if self._t_ns is None:
            self._t_ns = t_ns
            return
        dt = (t_ns - self._t_ns) * 1e-9
        if dt < 0:
            self.stats.skipped += 1  # out-of-order message: no time travel
            return
        self._t_ns = t_ns
        if dt == 0:
            return
        if dt > self.config.max_dt_s:  # a gap: do not extrapolate the old control
            self.stats.skipped += 1
            dt = self.config.max_dt_s
        if self._q[0] != dt:
            self._q = (dt, self._q_nominal * (self.config.nominal_dt_s / dt))
        self.ekf.predict(self._u, dt, self._q[1])

    def on_control(self, msg: VehicleControl) -> PoseEstimate:
        """Dead-reckoning sample of the car: predict to its stamp, then hold it."""
        if self.config.vehicle != "ackermann":
            raise ValueError("on_control needs vehicle='ackermann'")
        self.control(msg.stamp_ns, msg.speed_mps, msg.steering_rad)
        return self.pose_estimate(msg.stamp_ns)

    def control(self, stamp_ns: int, speed_mps: float, steering_rad: float) -> None:
        """Array-level :meth:`on_control` (no message objects; for benches)."""
        self._advance(int(stamp_ns))
        if math.isfinite(speed_mps) and math.isfinite(steering_rad):
            self._u = (float(speed_mps), float(steering_rad))
        else:
            self.stats.skipped += 1
        self.stats.controls += 1

    def on_odometry(self, msg: RobotOdometry) -> PoseEstimate:
        """Differential-drive odometry: the increment since the last message feeds the
        unicycle model (distance along the previous heading's chord, heading change)."""
        if self.config.vehicle != "unicycle":
            raise ValueError("on_odometry needs vehicle='unicycle'")
        pose = msg.pose
        if self._last_odom is not None:
            p0 = self._last_odom
            dth = wrap(pose.theta - p0.theta)
            dx, dy = pose.x - p0.x, pose.y - p0.y
            mid = p0.theta + 0.5 * dth
            d = dx * math.cos(mid) + dy * math.sin(mid)
            self.predict_increment(d, dth)
        self._last_odom = pose
        self._t_ns = msg.stamp_ns
        self.stats.controls += 1
        return self.pose_estimate(msg.stamp_ns)

    def predict_increment(self, d: float, dtheta: float) -> None:
        """Unicycle prediction with an odometry increment (m, rad) and its noise model."""
        c = self.config
        q = np.diag(
            [
                c.sigma_d_per_sqrt_m**2 * abs(d) + 1e-12,
                c.sigma_theta_per_sqrt_m**2 * abs(d)
                + c.sigma_theta_per_sqrt_rad**2 * abs(dtheta)
                + 1e-12,
            ]
        )
        self.ekf.predict(np.array([d, dtheta]), 0.0, q)

    # ------------------------------------------------------------ update
    def on_scan(self, msg: LandmarkScan) -> tuple[PoseEstimate, LandmarkMap]:
        """Associate, update and map with one scan; returns the pose and the map."""
        if self.config.vehicle == "ackermann":
            self._advance(msg.stamp_ns)
        else:
            self._t_ns = msg.stamp_ns
        offset = BEARING_OFFSETS.get(msg.bearing_zero)
        n = len(msg.ranges_m)
        if offset is None or len(msg.bearings_rad) != n:
            self.stats.skipped += 1
        else:
            z = np.empty((n, 2))
            z[:, 0] = msg.ranges_m
            # express bearings in the filter's (+pi/2) convention
            z[:, 1] = wrap(np.asarray(msg.bearings_rad, float) + (HALF_PI - offset))
            self.process(z)
        return self.pose_estimate(msg.stamp_ns), self.landmark_map(msg.stamp_ns)

    def scan(self, stamp_ns: int, z: np.ndarray) -> dict[str, int]:
        """Array-level :meth:`on_scan`: z (m, 2) in the filter's convention (pi/2 ahead)."""
        if self.config.vehicle == "ackermann":
            self._advance(int(stamp_ns))
        else:
            self._t_ns = int(stamp_ns)
        return self.process(z)

    def process(self, z: np.ndarray) -> dict[str, int]:
        """Data association, update and augmentation for observations z (m, 2) in the
        filter's convention (range, bearing with pi/2 ahead). Returns counts."""
        c = self.config
        ekf = self.ekf
        self.stats.scans += 1
        z = np.asarray(z, float).reshape(-1, 2)
        ok = np.isfinite(z).all(axis=1) & (z[:, 0] >= c.min_range_m) & (z[:, 0] <= c.max_range_m)
        self.stats.out_of_range += int(np.count_nonzero(~ok))
        z = z[ok]
        self.stats.observations += len(z)
        if len(z) == 0:
            return {"matched": 0, "new": 0}
        # candidate landmarks: those that could be within range (cheap distance pre-filter)
        cand = np.zeros(0, dtype=int)
        if ekf.n_landmarks:
            lm = ekf.landmarks
            xv = ekf.vehicle
            dist = np.hypot(lm[:, 0] - xv[0], lm[:, 1] - xv[1])
            cand = np.nonzero(dist < c.max_range_m + 10.0)[0]
        d2 = np.zeros((len(z), 0))
        assoc = np.full(len(z), -1, dtype=int)
        zp = hv = hm = None
        if len(cand):
            zp, hv, hm, s = ekf.predict_observations(cand)
            d2 = mahalanobis_matrix(z, zp, s)
            if c.association == "jcbb":
                near = np.nonzero((d2 < c.gate_chi2).any(axis=0))[0]
                if len(near):
                    zj, hph = ekf.joint_innovation_covariance(cand[near])
                    a = jcbb(z, zj, hph, ekf.r, d2[:, near], c.gate_chi2, 0.99, c.jcbb_max_nodes)
                    assoc = np.where(a >= 0, near[np.maximum(a, 0)], -1)
            else:
                assoc = nearest_neighbour(d2, c.gate_chi2)
        new_mask = classify_unmatched(d2, assoc, c.new_chi2)
        self.stats.ambiguous += int(np.count_nonzero((assoc < 0) & ~new_mask))
        matched = assoc >= 0
        if matched.any():
            j = assoc[matched]
            ekf.update(z[matched], cand[j], (zp[j], hv[j], hm[j]))  # type: ignore[index]
        self.stats.matched += int(np.count_nonzero(matched))
        n_new = 0
        if new_mask.any():
            zn = z[new_mask]
            xv = ekf.vehicle
            pos, gx, gz = inverse_observe(xv, zn, ekf.bearing_offset)
            pvv = ekf.vehicle_cov
            cov = gx @ pvv @ gx.transpose(0, 2, 1) + gz @ ekf.r @ gz.transpose(0, 2, 1)
            self.stats.new_candidates += len(zn)
            promote = self.tentative.observe(pos, cov, self.stats.scans)
            if promote.any():
                ekf.augment(zn[promote])
                n_new = int(np.count_nonzero(promote))
                self.stats.promoted += n_new
        return {"matched": int(np.count_nonzero(matched)), "new": n_new}

    # ------------------------------------------------------------ outputs
    def pose_estimate(self, stamp_ns: int) -> PoseEstimate:
        xv = self.ekf.vehicle
        p = self.ekf.vehicle_cov
        return PoseEstimate(
            stamp_ns=int(stamp_ns),
            pose=Pose2D(float(xv[0]), float(xv[1]), float(wrap(xv[2]))),
            covariance=tuple(float(v) for v in p.ravel()),
            frame="map",
            source="ekf_slam",
        )

    def landmark_map(self, stamp_ns: int) -> LandmarkMap:
        lm = self.ekf.landmarks
        cov = self.ekf.landmark_covariances()
        return LandmarkMap(
            stamp_ns=int(stamp_ns),
            ids=tuple(self.ekf.ids),
            xs=tuple(float(v) for v in lm[:, 0]),
            ys=tuple(float(v) for v in lm[:, 1]),
            cov_xx=tuple(float(v) for v in cov[:, 0, 0]),
            cov_xy=tuple(float(v) for v in cov[:, 0, 1]),
            cov_yy=tuple(float(v) for v in cov[:, 1, 1]),
        )
