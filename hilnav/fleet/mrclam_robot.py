"""One robot of ``hilnav fleet --scenario mrclam``: a recorded MRCLAM robot replayed into
the daemon's runtime (:class:`hilnav.runtime.RobotRuntime`: its queue, peers, Zenoh
session and log), scored against the motion capture.

- :class:`VelocityRuntimePipeline`: the services ``hilnav replay`` runs for one robot of
  an MRCLAM log (:class:`hilnav.replay.velocity_robot.VelocityRobotPipeline`: dead
  reckoning, the real-robot CP, the MRCLAM EKF) behind the runtime's pipeline interface.
  What the replay hands from robot to robot in one process goes over Zenoh here: the
  CP's ``pose_box`` and ``peer_sighting`` (peer topics), the EKF's ``pose`` and
  ``peer_fix`` (the pipeline's ``shared_outputs``);
- :class:`MrclamRobot`: a :class:`hilnav.fleet.robot.SimRobot` whose step puts the robot's
  recorded messages of the step through its queue as one read, tells its CP that the
  step's instant has come (its ticks up to it go out, also while the odometry pauses)
  and logs the motion capture of the step; it does not wait for its peers (their boxes
  are aged by their stamps). Its figures: the CP boxes at their ticks against the motion capture at the
  same instant (containment, areas, heading widths), the peers' boxes and sightings
  received and their age (wall time received minus the wall time their stamp was due),
  the EKF's RMSE and 3-sigma containment;
- :func:`pool` and :func:`line`: the run's figures and a line per robot for the command.
"""

from __future__ import annotations

import math
import threading
from collections import Counter
from typing import Any

import numpy as np

from drivers.clock import now_ns
from hilnav.analysis.containment import box_contains
from hilnav.bus import ZenohSettings
from hilnav.fleet.robot import SimRobot
from hilnav.fleet.score import percentile
from hilnav.replay.velocity_robot import SHARED_OUTPUTS, VelocityRobotPipeline
from hilnav.runtime import RobotRuntime
from hilnav.topics import log_topic
from localization.mrclam_cp_service import MrclamCpService
from msgs import Pose2D, PoseBox, PoseEstimate, wrap_angle

TWO_PI = 2.0 * math.pi


class VelocityRuntimePipeline:
    """One velocity-odometry robot's services with the interface the runtime calls
    (``hilnav.pipeline.Pipeline``'s: outputs handed to ``on_output`` as they are made).
    Its own boxes and EKF poses are kept for scoring."""

    shared_outputs = SHARED_OUTPUTS

    def __init__(self, robot: str, initial: Pose2D | None, on_output: Any = None) -> None:
        self.inner = VelocityRobotPipeline(robot, initial, ekf=None if initial else False)
        self.on_output = on_output
        self.latest: dict[str, Any] = {}
        self.worker = None
        self.boxes: list[PoseBox] = []
        self.poses: list[PoseEstimate] = []

    @property
    def services(self) -> list[str]:
        return list(self.inner.services)

    @property
    def cp(self) -> MrclamCpService:
        return next(s for s in self.inner.localizers if isinstance(s, MrclamCpService))

    def feed(self, topic: str, msg: Any, tag: Any = None) -> list[tuple[str, Any]]:
        out = self.inner.feed(topic, msg)
        self._take(out, tag)
        return out

    def _take(self, out: list[tuple[str, Any]], tag: Any) -> None:
        for t, m in out:
            self.latest[t] = m
            if t == "pose_box":
                self.boxes.append(m)
            elif t == "pose":
                self.poses.append(m)
            if self.on_output is not None:
                self.on_output(t, m, tag)

    def advance(self, stamp_ns: int, tag: Any = None) -> list[tuple[str, Any]]:
        """Everything recorded up to ``stamp_ns`` is in (the step's clock)."""
        out = self.inner.advance(stamp_ns)
        self._take(out, tag)
        return out

    def feed_other(self, robot: str, topic: str, msg: Any) -> list[tuple[str, Any]]:
        return self.inner.feed_other(robot, topic, msg)

    def drop_peer(self, robot: str) -> None:
        self.inner.drop_peer(robot)

    def close(self) -> None:
        return None


class MrclamRobot(SimRobot):
    """A recorded MRCLAM robot on the bus (module docstring). ``reference``: the EKF
    runs beside the CP."""

    def __init__(self, scenario: Any, name: str, base: Any, zenoh: ZenohSettings, **kw: Any):
        self._ekf = bool(kw.get("reference", True))
        super().__init__(scenario, name, base, zenoh, **kw)

    def make_runtime(self, zenoh: ZenohSettings, wake: threading.Event | None) -> RobotRuntime:
        initial = self.scenario.initial_pose(self.name) if self._ekf else None

        def pipeline(cfg: Any, *, on_output: Any = None, **_: Any) -> VelocityRuntimePipeline:
            return VelocityRuntimePipeline(self.name, initial, on_output)

        return RobotRuntime(
            self.cfg, zenoh=zenoh, prog=f"hilnav fleet: {self.name}", wake=wake,
            pipeline=pipeline, memo=self.memo,
        )  # fmt: skip

    @property
    def pipe(self) -> VelocityRuntimePipeline:
        return self.rt.pipeline

    def begin_step(self, s: int) -> None:
        assert self.devices is not None
        self.feed_step(s)
        # what was recorded up to the step's instant is in: the CP's ticks up to it go out
        now = now_ns()
        self.rt.guard("services", self.pipe.advance, self.devices.step_ns(s), now)
        topic = log_topic(self.name, "truth")
        for gt in self.devices.truth_messages(s):
            self.rt.log_msg(topic, gt, now)

    def peers_ready(self) -> bool:
        return True  # a peer's box is used with its age, whenever it comes

    def end_step(self, s: int) -> None:
        self.pump()
        self.steps += 1

    def result(self, dt: float) -> dict[str, Any]:
        rt, cp = self.rt, self.pipe.cp
        out = self.runtime_figures(dt)
        out.update(
            {
                "peer_sightings_received": rt.stats.by_topic.get("peer_sighting", 0),
                "sightings_sent": cp.sightings_sent,
                "sightings_heard": cp.sightings_heard,
                "cp_counts": dict(cp.counts),
                "cp_outliers_named": len(cp.cp.outliers),
            }
        )
        out.update(self._score_cp())
        out.update(self._score_ekf())
        return out

    def _truth(self, stamps: list[int]) -> tuple[np.ndarray, np.ndarray]:
        assert self.devices is not None
        base = self.devices.base_ns
        t = np.array([self.scenario.data_time(s, base) for s in stamps])
        return self.scenario.run.robots[self.devices.subject].truth_at(t)

    def _score_cp(self) -> dict[str, Any]:
        """The boxes at their ticks against the motion capture at the same instant."""
        boxes = self.pipe.boxes
        if not boxes:
            return {"cp_ticks": 0, "cp_scored": 0, "cp_contained": 0, "cp_areas_m2": []}
        pose, has = self._truth([bx.stamp_ns for bx in boxes])
        inside, areas, widths = [], [], []
        for bx, p, ok in zip(boxes, pose, has, strict=True):
            if not ok:
                continue
            inside.append(box_contains(bx, float(p[0]), float(p[1]), float(p[2])))
            areas.append(bx.area_m2 if math.isfinite(bx.area_m2) else None)
            w = bx.theta.hi - bx.theta.lo
            widths.append(min(w, TWO_PI) if math.isfinite(w) else TWO_PI)
        status = Counter(bx.status for bx in boxes)
        return {
            "cp_ticks": len(boxes),
            "cp_scored": len(inside),
            "cp_contained": int(sum(inside)),
            "cp_containment": float(np.mean(inside)) if inside else None,
            "cp_areas_m2": [None if a is None else round(a, 4) for a in areas],
            "cp_area_median_m2": _median(areas),
            "cp_heading_width_median_rad": float(np.median(widths)) if widths else None,
            "cp_status": dict(sorted(status.items())),
        }

    def _score_ekf(self) -> dict[str, Any]:
        """RMSE and 3-sigma containment (x, y, heading) of the EKF's poses."""
        poses = self.pipe.poses
        if not poses:
            return {}
        truth, has = self._truth([p.stamp_ns for p in poses])
        est = np.array([[p.pose.x, p.pose.y, p.pose.theta] for p in poses])[has]
        var = np.array([p.covariance[0::4] for p in poses])[has]
        e = est - truth[has]
        e[:, 2] = [wrap_angle(float(v)) for v in e[:, 2]]
        if not len(e):
            return {"ekf_scored": 0}
        inside = (np.abs(e) <= 3.0 * np.sqrt(np.clip(var, 0.0, None))).all(axis=1)
        return {
            "ekf_scored": len(e),
            "ekf_sq_m2": float(np.sum(e[:, 0] ** 2 + e[:, 1] ** 2)),
            "ekf_rmse_m": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))),
            "ekf_contained": int(inside.sum()),
            "ekf_containment": float(inside.mean()),
        }


def _median(areas: list[float | None]) -> float | None:
    """Median area, an unbounded box counting as infinite (None when that is the median)."""
    if not areas:
        return None
    m = float(np.median([math.inf if a is None else a for a in areas]))
    return m if math.isfinite(m) else None


def pool(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The run's figures: CP containment per robot and its minimum, the median box area
    over every robot's scored ticks, the peers' boxes and sightings, the EKF pooled."""
    scored = [r for r in results if r.get("cp_scored")]
    out: dict[str, Any] = {
        "cp_containment": {r["robot"]: r["cp_containment"] for r in scored},
        "cp_containment_min": min((r["cp_containment"] for r in scored), default=None),
        "cp_scored": sum(r.get("cp_scored", 0) for r in results),
        "cp_area_median_m2": _median([a for r in results for a in r.get("cp_areas_m2", [])]),
        "cp_area_median_by_robot_m2": {r["robot"]: r.get("cp_area_median_m2") for r in results},
        "peer_boxes_received": {r["robot"]: r["peer_boxes_received"] for r in results},
        "sightings_heard": {r["robot"]: r["sightings_heard"] for r in results},
        "sightings_sent": sum(r["sightings_sent"] for r in results),
    }
    n = sum(r.get("ekf_scored", 0) for r in results)
    if n:
        sq = sum(r.get("ekf_sq_m2", 0.0) for r in results)
        out["ekf_rmse_m"] = round(math.sqrt(sq / n), 4)
        out["ekf_containment"] = round(sum(r.get("ekf_contained", 0) for r in results) / n, 4)
    return out


def line(r: dict[str, Any]) -> str:
    """One line about a robot's result."""
    frac, area = r.get("cp_containment"), r.get("cp_area_median_m2")
    inside = f"{100 * frac:.1f} %" if frac is not None else "-"
    med = f"{area:.2f} m^2" if area is not None else "unbounded"
    ages = r["box_age_ms"]
    age = f"{percentile(ages, 50):.0f} ms" if ages else "-"
    ekf = f", EKF RMSE {r['ekf_rmse_m']:.3f} m" if r.get("ekf_scored") else ""
    return (
        f"{r['robot']}: CP boxes contain the truth {inside} of {r.get('cp_scored', 0)} ticks "
        f"(median area {med}), peer boxes {r['peer_boxes_received']} (median age {age}), "
        f"sightings sent {r['sightings_sent']} heard {r['sightings_heard']}{ekf}"
    )
