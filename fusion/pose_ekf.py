"""Pose EKF fed messages: wheel odometry, gyro and GPS (ekf-vs-cp.txt §2.1-2.2, eq. 1-4).

:class:`PoseEkf` is the EKF of fusion.pose_ekf_core (state, prediction eq. 1-4 with the
gyro fused as an increment, GPS bias states, Joseph updates, gating) fed messages:

- odometry and gyro go through the alignment front end (fusion.alignment), which decides
  which gyro change goes with which odometry step (late and bunched messages after a
  stall) and calls the EKF's predict/update; with ``arrival`` (fusion.arrival) the
  messages come in arrival order as the drivers stamp them and are put in stamp order
  first, and a gyro sample may release a held odometry message (its estimate is then
  returned by ``feed_gyro``). Odometry not newer than the last one is counted and skipped.
- GPS position (GpsFix.east_m/north_m, local metres of the NMEA driver): R from the GST
  standard deviations when present, else per-axis sigma = HDOP x UERE / sqrt(2) (HDOP x
  UERE is the horizontal DRMS); fixes without a 2D/3D fix or local metres are counted
  (gps_no_fix) and skipped. A fix whose stamp is older than the filter time by more than
  ``gps_max_lag_s``, or not newer than the previous fix, is rejected and counted
  (out_of_order_gps); a fix within the lag is applied now with R inflated by
  (speed x lag)^2, the distance driven meanwhile. A receiver's error is not white: it
  wanders with a correlation time of minutes (satellite geometry, ionosphere), so fixes
  taken every second are far from independent and an EKF treating them as white grows
  over-confident (its 3-sigma box stops containing the truth, the very point ekf-vs-cp
  makes). ``gps_error_correlation_s`` = tau > 0 scales R by max(1, tau / dt), dt the time
  since the last fix used: the fixes of one correlation time together carry about the
  information of one. Off (0) by default; bench/pose_ekf.py shows both.

Timeouts: a sensor silent for longer than its timeout (relative to the odometry stamps)
is flagged stale (``gps_stale``, ``gyro_stale``; transitions counted) and the filter
predicts on odometry alone.

Initial pose: ``initial`` (or ``set_pose``); without one, the first GPS fix sets x, y
and the heading stays at 0 with ``initial_sigma_theta_rad`` — give the start heading with
``set_pose`` when it is not east (the EKF cannot find a wholly unknown heading).

Output: ``PoseEstimate`` (frame ``map``) and ``bounds(k=3)`` -> ``PoseBox`` with the
k-sigma interval of each coordinate, to compare with constraint propagation's boxes.

Message-level API (what the pipeline calls):
    ekf = PoseEkf(PoseEkfParams(...), initial=Pose2D(...), arrival=ArrivalOrder(rate_hz))
    ekf.feed(msg) -> PoseEstimate | None   # the estimate when a step ran or a fix was used
    ekf.feed_odometry(m), ekf.feed_gyro(m), ekf.feed_gps(m)
    ekf.estimate() -> PoseEstimate; ekf.bounds(3.0) -> PoseBox
    ekf.set_pose(pose, stamp_ns=None, covariance=None); ekf.reset()
    ekf.counters() -> dict (for diagnostics); ekf.stale(now_ns) -> dict[str, bool]
Array-level API (fusion.pose_ekf_core): predict(dl, dr, dtheta_gyro=None, gyro_var=None),
update_position(z, R), update_heading(theta, var) -> UpdateResult.
"""

from __future__ import annotations

import numpy as np

from fusion.alignment import Advance, AlignedInput, GyroOdometryAlignment
from fusion.arrival import ArrivalOrder
from fusion.ekf_update import UpdateResult
from fusion.pose_ekf_core import PoseEkfCore
from fusion.pose_ekf_params import DEG, PoseEkfParams, gps_fix_measurement
from msgs import GpsFix, Pose2D, PoseEstimate
from msgs.stamps import set_back

NS = 1e-9
__all__ = ["DEG", "PoseEkf", "PoseEkfParams", "UpdateResult"]


class PoseEkf(AlignedInput, PoseEkfCore):
    """EKF on (x, y, theta) fed odometry, gyro and GPS messages (see module docstring)."""

    def __init__(
        self,
        params: PoseEkfParams | None = None,
        initial: Pose2D | None = None,
        arrival: ArrivalOrder | None = None,
    ):
        p = params or PoseEkfParams()
        self._align = GyroOdometryAlignment(p, arrival)
        self.gps_stale = True
        self._speed_mps = 0.0
        self._last_gps_ns: int | None = None
        self._last_gps_used_ns: int | None = None
        super().__init__(p, initial)

    def reset(self, pose: Pose2D | None = None, stamp_ns: int = 0) -> None:
        """Forget everything but the counters; restart at ``pose`` (default: the initial one).

        Without a pose the filter re-initialises its position from the next GPS fix when
        ``init_from_gps`` is set.
        """
        super().reset(pose, stamp_ns)
        self._align.reset()
        self._last_gps_ns = None
        self._last_gps_used_ns = None
        self._speed_mps = 0.0

    # -- message-level ---------------------------------------------------------------
    def _feed_other(self, msg: object) -> PoseEstimate | None:
        """A GpsFix -> the estimate (None if nothing changed); anything else: TypeError."""
        if isinstance(msg, GpsFix):
            return self.feed_gps(msg)
        raise TypeError(f"PoseEkf is fed RobotOdometry, GyroSample or GpsFix, not {type(msg)}")

    def _advanced(self, a: Advance | None) -> PoseEstimate | None:
        if a is None:
            return None
        step = a.step
        if step is None:  # first message, or re-baseline after a jump or a clock set back
            self.stamp_ns = a.stamp_ns
            return self.estimate()
        self.stamp_ns = step.t1_ns
        self._speed_mps = abs(step.ds_m) / step.dt_s if step.dt_s > 0 else 0.0
        last = self._last_gps_ns
        gps_stale = (
            last is None
            or set_back(step.t1_ns, last)  # the last fix is from before a clock set back
            or (step.t1_ns - last) * NS > self.params.gps_timeout_s
        )
        if gps_stale and not self.gps_stale:
            self._count.gps_timeouts += 1
        self.gps_stale = gps_stale
        return self.estimate()

    def gps_measurement(self, msg: GpsFix) -> tuple[np.ndarray, np.ndarray] | None:
        """(z, R) of a fix in local metres, or None when it has no usable position."""
        return gps_fix_measurement(msg, self.params)

    def feed_gps(self, msg: GpsFix) -> PoseEstimate | None:
        """Update on a fix; None if it was skipped (no fix, out of order, gated out)."""
        self._count.gps += 1
        meas = self.gps_measurement(msg)
        if meas is None:
            self._count.gps_no_fix += 1
            return None
        p = self.params
        lag_s = (self.stamp_ns - msg.stamp_ns) * NS
        last = self._last_gps_ns
        if (
            last is not None
            and set_back(msg.stamp_ns, last)
            and not set_back(msg.stamp_ns, self.stamp_ns)
        ):
            last = None  # the clock was set back, and the odometry has followed it
        if lag_s > p.gps_max_lag_s or (last is not None and msg.stamp_ns <= last):
            self._count.out_of_order_gps += 1
            return None
        self._last_gps_ns = msg.stamp_ns
        self.gps_stale = False
        z, r = meas
        if not self._pose_set and p.init_from_gps:
            self.init_from_fix(z, r)
            self._count.gps_init += 1
            return self.estimate()
        tau = p.gps_error_correlation_s
        if tau > 0.0 and self._last_gps_used_ns is not None:
            gap_s = (msg.stamp_ns - self._last_gps_used_ns) * NS
            r = r * max(1.0, tau / max(gap_s, 1e-3))
        d = self._speed_mps * abs(lag_s)
        if d > 0.0:
            r = r + np.eye(2) * d * d
        res = self.update_position(z, r, "gps")
        if not res.accepted:
            return None
        self._last_gps_used_ns = msg.stamp_ns
        return self.estimate()

    # -- diagnostics -----------------------------------------------------------------
    def stale(self, now_ns: int) -> dict[str, bool]:
        """Which inputs have been silent longer than their timeout at ``now_ns``."""
        p, a = self.params, self._align
        last_o = a.odo.last.stamp_ns if a.odo.last is not None else None

        def old(t: int | None, timeout: float) -> bool:  # or from before a clock set back
            return t is None or set_back(now_ns, t) or (now_ns - t) * NS > timeout

        return {
            "odometry": old(last_o, p.odometry_timeout_s),
            "gyro": old(a.gyro.last_stamp_ns, p.gyro_timeout_s),
            "gps": old(self._last_gps_ns, p.gps_timeout_s),
        }

    def counters(self) -> dict[str, int | float | bool]:
        c, a = self._count, self._align
        out: dict[str, int | float | bool] = {"odometry": a.odo.messages, "gyro": a.gyro.messages}
        out.update((k, v) for k, v in vars(c).items() if type(v) is int)
        out.update(c.extra)
        out.update(
            {
                "out_of_order_odometry": a.odo.out_of_order,
                "odometry_jumps": a.odo.jumps,
                "out_of_order_gyro": a.gyro.out_of_order,
                "gyro_discontinuities": a.gyro.discontinuities,
                "gyro_postponed": a.postponed,
                "gyro_deferred_steps": a.deferrals,
                "gyro_misaligned": a.misaligned,
                "gyro_timeouts": a.gyro_timeouts,
                "odometry_dropped": a.dropped,
                "gyro_late": a.late,
                "gyro_stale": a.gyro_stale,
                "gps_stale": self.gps_stale,
                "gyro_bias_radps": a.bias.bias_radps,
            }
        )
        return out
