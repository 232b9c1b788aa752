"""The scenario ``mrclam`` of ``hilnav fleet``: the robots of a recorded MRCLAM run (real
data), each replaying its own measurements in real time (or ``--rate`` times faster).

- :class:`MrclamScenario`: ``--robots N`` are the run's first N robots (``r<subject>``),
  from ``--start`` seconds after the run's start (its first odometry message) for
  ``--duration`` seconds; each robot's config, and where it starts (the motion capture
  at its first odometry message, as ``hilnav import mrclam`` says: the EKF's start; the
  CP starts knowing nothing);
- :class:`MrclamDevices`: one robot's recorded messages, as ``hilnav import mrclam``
  writes them (velocity odometry, landmark and robot range-bearing, the landmark map at
  the start; the motion capture as ``truth``, gaps flagged), step by step: step ``s``
  brings what was recorded up to ``s * dt_s`` of scenario time, stamped ``base_ns`` +
  scenario time (the data set's clock shifted; read to the microsecond). Sightings of
  robots outside the fleet are left out (counted in ``dropped``).

The robots themselves (their pipeline and scoring) are :mod:`hilnav.fleet.mrclam_robot`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hilnav.config import RobotConfig, config_data, parse_config
from hilnav.importers.mrclam import landmark_map, landmark_name, robot_name, to_ns
from localization.mrclam import MAX_TRUTH_GAP_S, MrclamRun, load_mrclam, robot_subjects
from msgs import GroundTruth, Pose2D, RangeBearing, VelocityOdometry, wrap_angle

#: Scenario time between two steps of the hosts (s): what a robot was recorded doing in
#: that time reaches its runtime as one read.
STEP_S = 0.05


def fleet_subjects(data: str | Path, robots: int) -> list[int]:
    """The run's first ``robots`` robot subjects; ValueError when it has fewer."""
    if not data:
        raise ValueError("--scenario mrclam needs --data DIR (an MRCLAM run directory)")
    d = Path(data)
    if not d.is_dir():
        raise ValueError(f"--data {data}: not a directory (an MRCLAM run directory is expected)")
    found = robot_subjects(d)
    if not 1 <= robots <= len(found):
        raise ValueError(f"--robots {robots}: {d.name} has {len(found)} robots ({found})")
    return found[:robots]


@dataclass
class MrclamScenario:
    """``hilnav fleet --scenario mrclam`` (module docstring)."""

    run: MrclamRun
    subjects: list[int]
    t0: float  # data time of scenario time 0 (s)
    duration_s: float
    dt: float = STEP_S

    @classmethod
    def build(cls, data: str, robots: int, duration_s: float, start_s: float = 0.0):
        subjects = fleet_subjects(data, robots)
        run = load_mrclam(data, subjects)
        t0 = run.start_s + max(0.0, start_s)
        if t0 >= run.end_s:
            raise ValueError(f"--start {start_s}: the run lasts {run.end_s - run.start_s:.0f} s")
        return cls(run, subjects, t0, min(duration_s, run.end_s - t0))

    @property
    def robot_class(self) -> type:
        from hilnav.fleet.mrclam_robot import MrclamRobot

        return MrclamRobot

    @property
    def names(self) -> list[str]:
        return [robot_name(n) for n in self.subjects]

    @property
    def dt_s(self) -> float:
        return self.dt

    @property
    def steps(self) -> int:
        return int(round(self.duration_s / self.dt)) + 1

    def subject(self, robot: str) -> int:
        return self.subjects[self.names.index(robot)]

    def initial_pose(self, robot: str) -> Pose2D:
        """The motion capture nearest the robot's first odometry message of the run."""
        rr = self.run.robots[self.subject(robot)]
        odo = rr.odometry[rr.odometry[:, 0] >= self.t0]
        t_first = float(odo[0, 0]) if len(odo) else self.t0
        j = int(np.argmin(np.abs(rr.truth[:, 0] - t_first)))
        x, y, th = (float(v) for v in rr.truth[j, 1:])
        return Pose2D(x, y, wrap_angle(th))

    def config(self, robot: str, base: RobotConfig) -> RobotConfig:
        """``base`` with this robot's name, the fleet and its start; no devices (the data
        set is the devices), none of the daemon's services but the peers' exchange
        (``services.localization.enabled``: the runtime takes the peers' boxes)."""
        p0 = self.initial_pose(robot)
        data = config_data(base)
        data.update(
            name=robot,
            fleet=sorted(set(self.names) | set(base.fleet)),
            initial_pose=[p0.x, p0.y, float(np.degrees(p0.theta))],
        )
        for dev in data["devices"].values():
            dev["enabled"] = False
        sv = data["services"]
        for name in ("heading", "pose", "mapping"):
            sv[name]["enabled"] = False
        sv["localization"]["enabled"] = True
        data["log"]["raw"] = False
        return parse_config(data, f"<fleet scenario mrclam: {robot}>")

    def devices(self, robot: str, base_ns: int) -> MrclamDevices:
        return MrclamDevices(self, self.subject(robot), base_ns)

    def reference(self, robot: str, cfg: RobotConfig, base_ns: int) -> None:
        return None  # the robots' own pipeline runs the EKF beside the CP

    def data_time(self, stamp_ns: int, base_ns: int) -> float:
        """The data set's time (s) of a stamp of this run."""
        return self.t0 + (stamp_ns - base_ns) * 1e-9


class MrclamDevices:
    """One robot's recorded messages, step by step (module docstring)."""

    def __init__(self, sc: MrclamScenario, subject: int, base_ns: int) -> None:
        self.sc, self.subject, self.base_ns = sc, subject, int(base_ns)
        self.name = robot_name(subject)
        rr = sc.run.robots[subject]
        t0_ns = int(to_ns(np.array([sc.t0]))[0])
        self._shift = self.base_ns - t0_ns
        end_ns = t0_ns + round(sc.duration_s * 1e9)

        def cut(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            ns = to_ns(a[:, 0]) if len(a) else np.empty(0, np.int64)
            keep = (ns >= t0_ns) & (ns <= end_ns)
            return a[keep], ns[keep]

        self.odo, self.odo_ns = cut(rr.odometry)
        meas, meas_ns = cut(rr.measurements)
        subj = meas[:, 1].astype(int)
        landmark = np.isin(subj, sorted(sc.run.landmarks))
        peer = np.isin(subj, [n for n in sc.subjects if n != subject])
        self.dropped = Counter({"self_or_outside_fleet": int((~landmark & ~peer).sum())})
        keep = landmark | peer
        self.meas, self.meas_ns, self.landmark = meas[keep], meas_ns[keep], landmark[keep]
        tr_ns = to_ns(rr.truth[:, 0])
        gaps = np.concatenate([[0], np.diff(tr_ns)])
        gaps = np.where(gaps > int(MAX_TRUTH_GAP_S * 1e9), gaps, 0)
        k = (tr_ns >= t0_ns) & (tr_ns <= end_ns)
        self.truth_rows, self.truth_ns, self.truth_gap = rr.truth[k], tr_ns[k], gaps[k]
        self.landmark_map = landmark_map(sc.run.landmarks, self.base_ns)

    def step_ns(self, s: int) -> int:
        """The stamp of step ``s``'s instant: what was recorded up to it is in the step."""
        return self.base_ns + round(s * self.sc.dt * 1e9)

    def _span(self, ns: np.ndarray, s: int) -> slice:
        """Rows of step ``s``: recorded after step s-1's instant, up to step s's."""
        hi = self.step_ns(s) - self._shift
        lo = self.step_ns(s - 1) - self._shift
        i = int(np.searchsorted(ns, lo, side="right")) if s else 0
        return slice(i, int(np.searchsorted(ns, hi, side="right")))

    def messages(self, s: int) -> list[tuple[str, Any]]:
        """(topic, msg) of step ``s`` in the import's order: by stamp, then velocity,
        landmark and robot measurements (the landmark map first, at step 0)."""
        items: list[tuple[int, int, int, str, Any]] = []
        sh = self._shift
        sl = self._span(self.odo_ns, s)
        for i in range(sl.start, sl.stop):
            st = int(self.odo_ns[i]) + sh
            v, w = float(self.odo[i, 1]), float(self.odo[i, 2])
            items.append((st, 0, i, "velocity", VelocityOdometry(st, v, w, True)))
        sl = self._span(self.meas_ns, s)
        for i in range(sl.start, sl.stop):
            st = int(self.meas_ns[i]) + sh
            n, r, b = int(self.meas[i, 1]), float(self.meas[i, 2]), float(self.meas[i, 3])
            if self.landmark[i]:
                m = RangeBearing(st, self.name, landmark_name(n), True, r, b, n)
                items.append((st, 1, i, "landmark_range_bearing", m))
            else:
                m = RangeBearing(st, self.name, robot_name(n), False, r, b, n)
                items.append((st, 2, i, "peer_range_bearing", m))
        items.sort(key=lambda it: it[:3])
        out = [("landmark_map", self.landmark_map)] if s == 0 else []
        return out + [(topic, m) for _, _, _, topic, m in items]

    def truth_messages(self, s: int) -> list[GroundTruth]:
        """The motion capture recorded in step ``s`` (``gap_before_s`` after a gap)."""
        sl = self._span(self.truth_ns, s)
        out = []
        for i in range(sl.start, sl.stop):
            x, y, th = (float(v) for v in self.truth_rows[i, 1:])
            gap = float(self.truth_gap[i]) * 1e-9
            st = int(self.truth_ns[i]) + self._shift
            out.append(GroundTruth(st, self.name, Pose2D(x, y, wrap_angle(th)), gap_before_s=gap))
        return out

    def relative_scan(self, s: int, targets: Any) -> None:
        return None  # the robot measurements are among the messages

    def truth(self, s: int) -> Pose2D:
        """The motion capture at step ``s``'s instant (interpolated; NaN in a gap)."""
        t = self.sc.t0 + s * self.sc.dt
        pose, ok = self.sc.run.robots[self.subject].truth_at(np.array([t]))
        if not ok[0]:
            return Pose2D(float("nan"), float("nan"), float("nan"))
        return Pose2D(float(pose[0, 0]), float(pose[0, 1]), float(pose[0, 2]))
