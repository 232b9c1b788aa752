"""Messages of the robot base (Pioneer 3-DX through ARCOS): odometry, commands, info; and
the velocity odometry of bases that report only their velocities (MRCLAM's iRobot Create)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from msgs.geometry import Pose2D


@dataclass(frozen=True, slots=True)
class RobotOdometry:
    """One server information packet (SIP) converted to SI units.

    pose is the robot's integrated odometry in the ``odom`` frame (15-bit positions
    unwrapped); velocities in m/s and rad/s; battery in volts. ``raw`` keeps every
    decoded SIP field by its ARIA name, in the robot's native units, so nothing is lost.
    """

    stamp_ns: int
    pose: Pose2D
    left_vel_mps: float
    right_vel_mps: float
    linear_vel_mps: float
    angular_vel_radps: float
    battery_v: float
    moving: bool
    motors_enabled: bool
    estop: bool = False
    left_stall: bool = False
    right_stall: bool = False
    front_bumpers: int = 0
    rear_bumpers: int = 0
    left_encoder: int | None = None
    right_encoder: int | None = None
    raw: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class VelocityOdometry:
    """The velocities a robot base reports for itself: forward (m/s) and yaw rate (rad/s,
    counter-clockwise), held until the next message. ``commanded`` is true when they are
    the commanded velocities (MRCLAM's odometry files) rather than measured at the
    wheels. Decoding refuses non-finite numbers."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    linear_mps: float
    angular_radps: float
    commanded: bool = False


@dataclass(frozen=True, slots=True)
class VelocityCommand:
    """A velocity command: linear m/s forward, angular rad/s counter-clockwise.

    If ``left_mps``/``right_mps`` are set the command is per wheel (ARCOS VEL2) and the
    linear/angular fields are ignored. Decoding refuses non-finite numbers.
    """

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    linear_mps: float = 0.0
    angular_radps: float = 0.0
    left_mps: float | None = None
    right_mps: float | None = None
    source: str = ""


@dataclass(frozen=True, slots=True)
class RobotInfo:
    """What a robot said about itself while connecting (SYNC2 reply and CONFIG packet)."""

    stamp_ns: int
    name: str
    robot_class: str
    subclass: str
    config: dict[str, int | str] = field(default_factory=dict)
