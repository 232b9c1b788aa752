"""Every topic of hilnav in one table: its message class, where it comes from, and who
sees it.

A topic name is the last part of a Zenoh key ``hilnav/<robot>/<topic>`` and of an MCAP
topic ``/<robot>/<topic>``; the raw bytes of a device are ``raw/<device>``
(msgs.RawBytes). Each :class:`Topic` says:

- ``source``: ``device`` (decoded by a driver), ``bus`` (arrives on Zenoh for this
  robot: commands), ``services`` (produced by the pipeline: replay drops these from its
  input and produces them again), ``daemon`` (health), ``sim`` (the simulated world:
  ground truth) or ``external`` (measured by a sensor hilnav has no driver for: simulated
  in the fleet scenario, or imported from a data set);
- ``service_input``: the pipeline takes it;
- ``published``: the daemon puts it on Zenoh (the others are logged only);
- ``peer``: the daemon takes it from the other fleet robots (cooperative localization).

The bus, the daemon, the pipeline, replay and the docs all read this table.
"""

from __future__ import annotations

from dataclasses import dataclass

from msgs import (
    AssociationReport,
    DaemonStatus,
    DeviceDiagnostics,
    GpsFix,
    GpsSky,
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    IrScan,
    LandmarkMap,
    LandmarkScan,
    OccupancyGridMsg,
    PeerFix,
    PeerSighting,
    PoseBox,
    PoseEstimate,
    RangeBearing,
    RawBytes,
    RelativeScan,
    RobotInfo,
    RobotOdometry,
    VehicleControl,
    VelocityCommand,
    VelocityOdometry,
)


@dataclass(frozen=True)
class Topic:
    name: str
    cls: type
    source: str
    doc: str
    service_input: bool = False
    published: bool = False
    peer: bool = False


_TABLE = (
    Topic("odometry", RobotOdometry, "device", "Pioneer SIP: odometry pose, wheel speeds, battery",
          service_input=True, published=True),
    Topic("gyro", GyroSample, "device", "CruzCore packet: yaw rate and integrated angle",
          service_input=True, published=True),
    Topic("gps", GpsFix, "device", "one NMEA epoch: position, local east/north, quality",
          service_input=True, published=True),
    Topic("sky", GpsSky, "device", "GPS satellites in view and used, DOPs (NMEA GSV, GSA)",
          published=True),
    Topic("ir", IrScan, "device", "one IR board sample: a range per Sharp sensor",
          service_input=True, published=True),
    Topic("info", RobotInfo, "device", "what the Pioneer said of itself (SYNC2, CONFIG)",
          published=True),
    Topic("cmd_vel", VelocityCommand, "bus", "velocity command for this robot (fleet only)"),
    Topic("heading", HeadingEstimate, "services", "encoder + gyro heading (ir-grid-mapping "
          "eq. 1-4)", published=True),
    Topic("pose", PoseEstimate, "services", "pose EKF: odometry, gyro, GPS (ekf-vs-cp eq. 1-4); "
          "MRCLAM replay: the MRCLAM EKF (velocity odometry, range-bearing)", published=True),
    Topic("peer_fix", PeerFix, "services", "MRCLAM: a robot's position fix of another robot "
          "it measured (its estimate + range-bearing), for that robot's EKF (on Zenoh in "
          "hilnav fleet: a shared output of the MRCLAM robots' pipeline)"),
    Topic("pose_box", PoseBox, "services", "guaranteed CP box (ekf-vs-cp eq. 5); MRCLAM: the "
          "real-robot CP's box every 0.1 s, with its guarantee's status",
          published=True, peer=True),
    Topic("peer_sighting", PeerSighting, "services", "MRCLAM: a robot's range-bearing "
          "measurement of another robot with its own CP box, for that robot's CP",
          published=True, peer=True),
    Topic("map", OccupancyGridMsg, "services", "IR occupancy grid (ir-grid-mapping eq. 5-8)",
          published=True),
    Topic("association", AssociationReport, "services", "one data-association step's result",
          published=True),
    Topic("landmarks", LandmarkMap, "services", "EKF-SLAM landmark map"),
    Topic("slam_pose", PoseEstimate, "services", "EKF-SLAM vehicle pose"),
    Topic("dead_reckoning", PoseEstimate, "services", "velocity odometry integrated from the "
          "initial pose, uncorrected (replay of velocity-odometry data sets)"),
    Topic("diagnostics", DeviceDiagnostics, "daemon", "per-device link counters, 1 Hz",
          published=True),
    Topic("status", DaemonStatus, "daemon", "the daemon's loop, bus and motion gate, 1 Hz",
          published=True),
    Topic("truth", GroundTruth, "sim", "the simulated world's true pose (an imported data "
          "set's reference poses)"),
    Topic("reference_map", OccupancyGridMsg, "external", "a data set's map at its reference "
          "poses: what hilnav analyze scores the maps against"),
    Topic("relative", RelativeScan, "external", "one range-bearing scan of the other robots "
          "(cooperative CP)", service_input=True),
    Topic("control", VehicleControl, "external", "car-like vehicle control (speed, steering)",
          service_input=True),
    Topic("landmark_scan", LandmarkScan, "external", "range-bearing landmark detections",
          service_input=True),
    Topic("velocity", VelocityOdometry, "external", "velocity odometry: forward speed and yaw "
          "rate (MRCLAM: commanded)", service_input=True),
    Topic("landmark_range_bearing", RangeBearing, "external", "range-bearing to a known "
          "landmark of landmark_map, named (no bounds)", service_input=True),
    Topic("peer_range_bearing", RangeBearing, "external", "range-bearing to another robot, "
          "named (no bounds)", service_input=True),
    Topic("landmark_map", LandmarkMap, "external", "a data set's known (surveyed) landmark "
          "map, logged once per robot at its start", service_input=True),
)  # fmt: skip

TOPICS: dict[str, Topic] = {t.name: t for t in _TABLE}
RAW_PREFIX = "raw/"

SERVICE_INPUTS: frozenset[str] = frozenset(t.name for t in _TABLE if t.service_input)
SERVICE_OUTPUTS: frozenset[str] = frozenset(t.name for t in _TABLE if t.source == "services")
PUBLISHED: frozenset[str] = frozenset(t.name for t in _TABLE if t.published)
PEER_TOPICS: tuple[str, ...] = tuple(t.name for t in _TABLE if t.peer)
# Published at once on Zenoh, never held to be batched with others (Zenoh's express): what
# robots and operators act on, the services' estimates and the commands. Device data is
# batched by Zenoh (fewer writes for the 100 Hz gyro).
EXPRESS: frozenset[str] = frozenset(
    t.name for t in _TABLE if (t.published and t.source == "services") or t.source == "bus"
)
# The topic a driver's message goes on, by its class (device topics only).
DEVICE_TOPICS: dict[type, str] = {t.cls: t.name for t in _TABLE if t.source == "device"}

# What the queryables hilnav/<robot>/query/<name> answer with.
QUERIES: dict[str, type] = {"pose": PoseEstimate, "map": OccupancyGridMsg, "info": RobotInfo}


def topic_type(topic: str) -> type | None:
    """The message class of a topic name, or None if hilnav does not know it."""
    if topic.startswith(RAW_PREFIX):
        return RawBytes
    t = TOPICS.get(topic)
    return t.cls if t is not None else None


def raw_topic(device: str) -> str:
    return RAW_PREFIX + device


def log_topic(robot: str, topic: str) -> str:
    """The MCAP topic of a robot's topic: ``/<robot>/<topic>``."""
    return f"/{robot}/{topic}"


def split_log_topic(topic: str) -> tuple[str, str]:
    """``/<robot>/<name...>`` -> (robot, name); ("", topic) when there is no robot part."""
    parts = topic.strip("/").split("/", 1)
    if len(parts) == 2:
        return parts[0], parts[1]
    return "", parts[0]
