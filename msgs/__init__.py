"""Typed messages shared by every layer of hilnav (layer 1: no I/O; stdlib and the
numpy-free numerics.angles only).

SI units throughout (metres, radians, seconds, volts); stamps are integer nanoseconds.
``wrap_angle`` is numerics.angles.wrap_angle, re-exported for every layer above.
"""

from msgs.codec import DecodeError, decode, encode, from_dict, json_schema, schema_name, to_dict
from msgs.diagnostics import DaemonStatus, DeviceDiagnostics
from msgs.estimates import HeadingEstimate, PeerFix, PeerSighting, PoseBox, PoseEstimate
from msgs.geometry import Interval, Pose2D
from msgs.landmarks import LandmarkMap, LandmarkScan, VehicleControl
from msgs.log import GroundTruth, RawBytes
from msgs.mapping import AssociationReport, OccupancyGridMsg
from msgs.relative import RangeBearing, RelativeMeasurement, RelativeScan
from msgs.robot import RobotInfo, RobotOdometry, VelocityCommand, VelocityOdometry
from msgs.sensors import GpsFix, GpsSatellite, GpsSky, GyroSample, IrScan, IrStatus
from numerics.angles import wrap_angle

__all__ = [
    "AssociationReport",
    "DaemonStatus",
    "DecodeError",
    "DeviceDiagnostics",
    "GpsFix",
    "GpsSatellite",
    "GpsSky",
    "GroundTruth",
    "GyroSample",
    "HeadingEstimate",
    "Interval",
    "IrScan",
    "IrStatus",
    "LandmarkMap",
    "LandmarkScan",
    "OccupancyGridMsg",
    "PeerFix",
    "PeerSighting",
    "Pose2D",
    "PoseBox",
    "PoseEstimate",
    "RangeBearing",
    "RawBytes",
    "RelativeMeasurement",
    "RelativeScan",
    "RobotInfo",
    "RobotOdometry",
    "VehicleControl",
    "VelocityCommand",
    "VelocityOdometry",
    "decode",
    "encode",
    "from_dict",
    "json_schema",
    "schema_name",
    "to_dict",
    "wrap_angle",
]
