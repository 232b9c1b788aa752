"""Foxglove views of hilnav messages: pure conversions to Foxglove's well-known JSON schemas.

The Foxglove app draws a message without a plugin when its channel's schema is named as one
of Foxglove's (``foxglove.PoseInFrame`` ...) and its JSON has those fields: times are
``{"sec", "nsec"}``, bytes are base64, orientations are quaternions. :func:`views` turns one
native message into zero or more such views, each ``(topic, schema_name, dict)``:

| native topic (``/<robot>/...``) | view | view topic |
|---|---|---|
| ``pose`` (PoseEstimate)     | foxglove.PoseInFrame, foxglove.FrameTransform map-><robot>/odom | ``/<robot>/fox/pose``, ``/tf`` |
| ``heading`` (HeadingEstimate)| foxglove.PoseInFrame        | ``/<robot>/fox/heading`` |
| ``truth`` (GroundTruth)     | foxglove.PoseInFrame        | ``/<robot>/fox/truth`` |
| ``odometry`` (RobotOdometry)| foxglove.FrameTransform <robot>/odom-><robot>/base_link | ``/tf`` |
| ``gps`` (GpsFix with lat/lon)| foxglove.LocationFix       | ``/<robot>/fox/gps`` |
| ``pose_box`` (PoseBox)      | foxglove.SceneUpdate: a cube and two heading arrows | ``/<robot>/fox/pose_box`` |
| landmarks (LandmarkMap: ``xs``/``ys``) | foxglove.SceneUpdate: spheres (3-sigma size) | ``/<robot>/fox/<topic>`` |

The map (``msgs.OccupancyGridMsg``) already *is* a ``foxglove.Grid`` and needs no view.
map->odom needs the latest odometry pose: :class:`ViewState` keeps it (pure, no clock).
The JSON Schemas of the view schemas are in :mod:`hilnav.log.foxglove_schemas`.

Frames follow REP-105 with one tree per robot under a shared world frame, so the logs of
several robots open together without clashing: ``map`` (shared) -> ``<robot>/odom`` ->
``<robot>/base_link`` (:func:`robot_frame`). A message's own frame (``map`` for every
estimate, box and landmark map today) is kept when it is ``map`` and prefixed with the
robot otherwise; the GPS fix is in ``<robot>/base_link`` (the antenna on the robot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from hilnav.topics import split_log_topic
from msgs import (
    GpsFix,
    GroundTruth,
    HeadingEstimate,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RobotOdometry,
    wrap_angle,
)

View = tuple[str, str, dict[str, Any]]

TF_TOPIC = "/tf"
VIEW_PREFIX = "fox"
WORLD_FRAME = "map"  # shared by every robot (REP-105 map)
ODOM_FRAME = "odom"  # per robot: <robot>/odom
BASE_FRAME = "base_link"  # per robot: <robot>/base_link

BOX_COLOR = {"r": 0.2, "g": 0.5, "b": 1.0, "a": 0.35}
ARROW_COLOR = {"r": 0.1, "g": 0.3, "b": 0.9, "a": 0.9}
LANDMARK_COLOR = {"r": 0.1, "g": 0.7, "b": 0.2, "a": 0.8}
# GPS user-equivalent range error (m) turning an HDOP into an approximate std deviation.
GPS_UERE_M = 5.0


def robot_frame(robot: str, frame: str) -> str:
    """The frame ``frame`` of ``robot`` in the views: ``map`` is shared, others are per robot.

    ``robot_frame("r1", "odom") == "r1/odom"``; ``map``, an already qualified name
    (``r2/odom``) and any frame of a topic without a robot are kept as they are.
    """
    if not robot or frame == WORLD_FRAME or "/" in frame:
        return frame
    return f"{robot}/{frame}"


def time_of(stamp_ns: int) -> dict[str, int]:
    """A Foxglove time {sec, nsec} of a nanosecond stamp (clamped at 0: no negative times)."""
    sec, nsec = divmod(max(0, int(stamp_ns)), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def quaternion_z(theta: float) -> dict[str, float]:
    """The quaternion of a rotation by ``theta`` about +z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2.0), "w": math.cos(theta / 2.0)}


def pose3(p: Pose2D, z: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": p.x, "y": p.y, "z": z}, "orientation": quaternion_z(p.theta)}


def pose_in_frame(stamp_ns: int, frame: str, p: Pose2D) -> dict[str, Any]:
    return {"timestamp": time_of(stamp_ns), "frame_id": frame, "pose": pose3(p)}


def frame_transform(stamp_ns: int, parent: str, child: str, p: Pose2D) -> dict[str, Any]:
    """Child frame's pose ``p`` in the parent frame."""
    return {
        "timestamp": time_of(stamp_ns),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": {"x": p.x, "y": p.y, "z": 0.0},
        "rotation": quaternion_z(p.theta),
    }


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """a ⊕ b: the pose b (expressed in a's frame) in a's parent frame."""
    c, s = math.cos(a.theta), math.sin(a.theta)
    return Pose2D(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.theta + b.theta))


def inverse(a: Pose2D) -> Pose2D:
    c, s = math.cos(a.theta), math.sin(a.theta)
    return Pose2D(-c * a.x - s * a.y, s * a.x - c * a.y, wrap_angle(-a.theta))


def location_fix(fix: GpsFix, frame: str = BASE_FRAME) -> dict[str, Any] | None:
    """foxglove.LocationFix of a fix with a position (None without lat/lon).

    Covariance (ENU, m^2): per-axis std deviations when the receiver gave them
    (DIAGONAL_KNOWN), else HDOP x UERE (APPROXIMATED), else UNKNOWN zeros.
    """
    if fix.lat_deg is None or fix.lon_deg is None:
        return None
    cov = [0.0] * 9
    ctype = 0
    if fix.std_lat_m is not None and fix.std_lon_m is not None:
        cov[0], cov[4] = fix.std_lon_m**2, fix.std_lat_m**2
        cov[8] = (fix.std_alt_m if fix.std_alt_m is not None else 2.0 * fix.std_lat_m) ** 2
        ctype = 2
    elif fix.hdop is not None:
        h = (fix.hdop * GPS_UERE_M) ** 2
        v = ((fix.vdop if fix.vdop is not None else 2.0 * fix.hdop) * GPS_UERE_M) ** 2
        cov[0] = cov[4] = h
        cov[8] = v
        ctype = 1
    alt = fix.alt_msl_m if fix.alt_msl_m is not None else 0.0
    return {
        "timestamp": time_of(fix.stamp_ns),
        "frame_id": frame,
        "latitude": fix.lat_deg,
        "longitude": fix.lon_deg,
        "altitude": alt,
        "position_covariance": cov,
        "position_covariance_type": ctype,
    }


def _entity(stamp_ns: int, frame: str, ident: str, **prims: list[dict[str, Any]]) -> dict:
    ent: dict[str, Any] = {
        "timestamp": time_of(stamp_ns),
        "frame_id": frame,
        "id": ident,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": False,
        "metadata": [],
        "arrows": [],
        "cubes": [],
        "spheres": [],
        "cylinders": [],
        "lines": [],
        "triangles": [],
        "texts": [],
        "models": [],
    }
    ent.update(prims)
    return ent


def pose_box_scene(box: PoseBox, frame: str | None = None) -> dict[str, Any]:
    """foxglove.SceneUpdate of a CP box: a flat cube over x/y and arrows at theta lo/hi
    (no arrows for an unbounded heading; a deletion for an empty or unbounded box).

    ``frame`` is the entity's frame (default: the box's own)."""
    ident = f"{box.robot}/pose_box"
    frame = box.frame if frame is None else frame
    bounded = all(math.isfinite(v) for v in (box.x.lo, box.x.hi, box.y.lo, box.y.hi))
    if box.x.empty or box.y.empty or box.theta.empty or not bounded:
        deletion = {"timestamp": time_of(box.stamp_ns), "type": 0, "id": ident}
        return {"deletions": [deletion], "entities": []}
    cx, cy = (box.x.lo + box.x.hi) / 2.0, (box.y.lo + box.y.hi) / 2.0
    wx, wy = max(box.x.width, 1e-3), max(box.y.width, 1e-3)
    cube = {
        "pose": pose3(Pose2D(cx, cy, 0.0), z=0.01),
        "size": {"x": wx, "y": wy, "z": 0.02},
        "color": BOX_COLOR,
    }
    length = max(0.3, 0.5 * max(wx, wy))
    arrows = [
        {
            "pose": pose3(Pose2D(cx, cy, th), z=0.03),
            "shaft_length": 0.8 * length,
            "shaft_diameter": 0.02,
            "head_length": 0.2 * length,
            "head_diameter": 0.06,
            "color": ARROW_COLOR,
        }
        for th in (box.theta.lo, box.theta.hi)
        if math.isfinite(th)
    ]
    return {
        "deletions": [],
        "entities": [_entity(box.stamp_ns, frame, ident, cubes=[cube], arrows=arrows)],
    }


def landmark_scene(stamp_ns: int, frame: str, ident: str, points: list[tuple]) -> dict:
    """foxglove.SceneUpdate with one sphere per landmark (x, y[, diameter])."""
    spheres = []
    for p in points:
        d = float(p[2]) if len(p) > 2 and p[2] else 0.3
        spheres.append(
            {
                "pose": pose3(Pose2D(float(p[0]), float(p[1]), 0.0), z=d / 2.0),
                "size": {"x": d, "y": d, "z": d},
                "color": LANDMARK_COLOR,
            }
        )
    return {"deletions": [], "entities": [_entity(stamp_ns, frame, ident, spheres=spheres)]}


def _landmark_points(msg: Any) -> list[tuple] | None:
    """(x, y, size) per landmark of a map-frame landmark message, else None.

    Understood: ``xs``/``ys`` tuples (msgs.landmarks.LandmarkMap; the sphere's size is the
    3-sigma extent of ``cov_xx``/``cov_yy`` when present), or ``landmarks`` items with
    ``x``/``y`` (or ``x_m``/``y_m``).
    """
    xs, ys = getattr(msg, "xs", None), getattr(msg, "ys", None)
    if isinstance(xs, tuple | list) and isinstance(ys, tuple | list) and len(xs) == len(ys):
        cxx = getattr(msg, "cov_xx", ()) or ()
        cyy = getattr(msg, "cov_yy", ()) or ()
        pts = []
        for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
            size = None
            if i < len(cxx) and i < len(cyy):
                size = 6.0 * math.sqrt(max(float(cxx[i]), float(cyy[i]), 0.0))
            pts.append((float(x), float(y), max(size, 0.2) if size is not None else None))
        return pts
    lms = getattr(msg, "landmarks", None)
    if not isinstance(lms, tuple | list):
        return None
    pts = []
    for lm in lms:
        x, y = getattr(lm, "x", None), getattr(lm, "y", None)
        if x is None or y is None:
            x, y = getattr(lm, "x_m", None), getattr(lm, "y_m", None)
        if not isinstance(x, int | float) or not isinstance(y, int | float):
            return None  # landmarks not in map coordinates (e.g. range/bearing): no view
        pts.append((x, y, getattr(lm, "diameter_m", None)))
    return pts


@dataclass
class ViewState:
    """What the views remember between messages: the latest odometry pose per robot."""

    odom: dict[str, Pose2D] = field(default_factory=dict)


def _pose_views(robot: str, topic: str, msg: PoseEstimate, state: ViewState | None) -> list[View]:
    """The estimate in its frame, and map -> <robot>/odom when it is in ``map``."""
    frame = robot_frame(robot, msg.frame)
    out: list[View] = [
        (topic, "foxglove.PoseInFrame", pose_in_frame(msg.stamp_ns, frame, msg.pose))
    ]
    odom = state.odom.get(robot) if state is not None else None
    if odom is not None and msg.frame == WORLD_FRAME:
        map_odom = compose(msg.pose, inverse(odom))
        child = robot_frame(robot, ODOM_FRAME)
        tf = frame_transform(msg.stamp_ns, WORLD_FRAME, child, map_odom)
        out.append((TF_TOPIC, "foxglove.FrameTransform", tf))
    return out


_VIEWED = (PoseEstimate, HeadingEstimate, GroundTruth, RobotOdometry, GpsFix, PoseBox)


@cache
def may_have_views(cls: type) -> bool:
    """False when :func:`views` never gives a view of a ``cls`` message (gyro samples, raw
    bytes, IR scans ...), so the log's encoder need not ask for every one."""
    if issubclass(cls, _VIEWED):
        return True
    return (hasattr(cls, "xs") and hasattr(cls, "ys")) or hasattr(cls, "landmarks")


def views_use_state(cls: type) -> bool:
    """True when :func:`views` of a ``cls`` message reads or writes its ``state`` (the
    estimate's map -> odom, the odometry's pose): its views are then not a function of
    the topic and the message alone."""
    return issubclass(cls, PoseEstimate | RobotOdometry)


def views(topic: str, msg: Any, state: ViewState | None = None) -> list[View]:
    """Foxglove views of the message ``msg`` logged on ``topic`` (may be empty)."""
    robot, name = split_log_topic(topic)
    vtopic = f"/{robot}/{VIEW_PREFIX}/{name}" if robot else f"/{VIEW_PREFIX}/{name}"
    if isinstance(msg, PoseEstimate):
        return _pose_views(robot, vtopic, msg, state)
    if isinstance(msg, HeadingEstimate | GroundTruth):
        view = pose_in_frame(msg.stamp_ns, WORLD_FRAME, msg.pose)
        return [(vtopic, "foxglove.PoseInFrame", view)]
    if isinstance(msg, RobotOdometry):
        if state is not None:
            state.odom[robot] = msg.pose
        odom, base = robot_frame(robot, ODOM_FRAME), robot_frame(robot, BASE_FRAME)
        tf = frame_transform(msg.stamp_ns, odom, base, msg.pose)
        return [(TF_TOPIC, "foxglove.FrameTransform", tf)]
    if isinstance(msg, GpsFix):
        fix = location_fix(msg, robot_frame(robot, BASE_FRAME))
        return [] if fix is None else [(vtopic, "foxglove.LocationFix", fix)]
    if isinstance(msg, PoseBox):
        scene = pose_box_scene(msg, robot_frame(robot, msg.frame))
        return [(vtopic, "foxglove.SceneUpdate", scene)]
    pts = _landmark_points(msg)
    if pts is None:
        return []
    stamp = int(getattr(msg, "stamp_ns", 0) or 0)
    frame = robot_frame(robot, str(getattr(msg, "frame", WORLD_FRAME) or WORLD_FRAME))
    scene = landmark_scene(stamp, frame, f"{robot}/{name}", pts)
    return [(vtopic, "foxglove.SceneUpdate", scene)]
