"""The schema of a robot's configuration: one frozen dataclass per TOML table.

Each field's ``metadata`` holds its check (a test and the problem to report); the loader
(:mod:`hilnav.config.loader`) enforces them. Angles in the file are in degrees
(``ir_mounts`` yaw), everything else SI. Device ports are a serial device path,
``tcp://host:port``, a file of recorded bytes, or ``sim`` (served by ``hilnav fake``).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any

from hilnav.bus import ZenohSettings, check_name
from hilnav.cmdvel import CmdVelLimits

DEG = math.pi / 180.0


class ConfigError(ValueError):
    """A configuration problem: the message names the key, the bad value and the fix."""


def _check(test: typing.Callable[[Any], bool], problem: str) -> dict[str, Any]:
    return {"check": (test, problem)}


def _positive(eg: str) -> dict[str, Any]:
    return _check(lambda v: v > 0, f"must be > 0 (e.g. {eg})")


def _non_negative(eg: str) -> dict[str, Any]:
    return _check(lambda v: v >= 0, f"must be >= 0 (e.g. {eg}; 0 = none)")


def _choice(*options: Any) -> dict[str, Any]:
    return _check(lambda v: v in options, "must be one of " + ", ".join(map(repr, options)))


def _baud(eg: str) -> dict[str, Any]:
    return _check(lambda v: 50 <= v <= 4_000_000, f"a serial baud rate, 50..4000000 (e.g. {eg})")


def _fraction() -> dict[str, Any]:
    return _check(lambda v: 0.0 <= v <= 1.0, "must be a fraction between 0 and 1")


def _name_ok(v: str) -> bool:
    try:
        check_name(v)
    except ValueError:
        return False
    return True


# -- devices -----------------------------------------------------------------------------
@dataclass(frozen=True)
class ArcosDevice:
    """The Pioneer base (ARCOS over serial or tcp://, e.g. MobileSim on port 8101)."""

    enabled: bool = True
    port: str = "sim"
    baud: int = field(default=9600, metadata=_baud("9600"))


@dataclass(frozen=True)
class IrDevice:
    """The IR ADC board: on a serial port (link "serial") or on CAN (link "can")."""

    enabled: bool = True
    link: str = field(default="can", metadata=_choice("serial", "can"))
    port: str = "sim"  # serial link: the port; can link with slcan: the adapter's port
    baud: int = field(default=115200, metadata=_baud("115200"))
    can_interface: str = "slcan"  # python-can interface; "": python-can's own config/env
    can_channel: str = ""  # empty: the port (slcan); e.g. can0 for socketcan
    can_bitrate: int = field(
        default=500_000,
        metadata=_check(lambda v: 5_000 <= v <= 8_000_000, "a CAN bit rate, 5000..8000000"),
    )
    board_id: int = field(default=1, metadata=_check(lambda v: 0 <= v <= 15, "must be 0..15"))
    rate_hz: int = field(default=20, metadata=_check(lambda v: 1 <= v <= 1000, "must be 1..1000"))
    adc_bits: int = field(default=10, metadata=_choice(10, 12))
    vref_v: float = field(default=5.0, metadata=_positive("5.0"))
    median_window: int = field(default=3, metadata=_check(lambda v: 1 <= v <= 15, "1..15"))
    can: dict[str, Any] = field(default_factory=dict)  # more can.Bus(...) arguments


@dataclass(frozen=True)
class GyroDevice:
    """The CruzCore gyro."""

    enabled: bool = True
    port: str = "sim"
    baud: int = field(default=115200, metadata=_baud("115200"))
    rate_hz: int = field(default=100, metadata=_check(lambda v: 1 <= v <= 1000, "1..1000"))


@dataclass(frozen=True)
class GpsDevice:
    """The NMEA GPS; ``datum`` = [lat, lon] degrees of the local east/north origin."""

    enabled: bool = True
    port: str = "sim"
    baud: int = field(default=9600, metadata=_baud("9600"))
    datum: tuple[float, float] = field(
        default=(37.5665, 126.9780),
        metadata=_check(
            lambda v: -90 <= v[0] <= 90 and -180 <= v[1] <= 180,
            "must be [latitude, longitude] in degrees",
        ),
    )


@dataclass(frozen=True)
class Devices:
    arcos: ArcosDevice = field(default_factory=ArcosDevice)
    ir: IrDevice = field(default_factory=IrDevice)
    gyro: GyroDevice = field(default_factory=GyroDevice)
    gps: GpsDevice = field(default_factory=GpsDevice)

    def sections(self) -> list[tuple[str, Any]]:
        """(name, section) of every device, in table order."""
        return [(f.name, getattr(self, f.name)) for f in dataclasses.fields(self)]


# -- geometry and noise ------------------------------------------------------------------
_PAPER_MOUNTS_DEG = (
    (0.20, 0.05, 15.0),
    (0.20, -0.05, -15.0),
    (0.17, 0.13, 50.0),
    (0.17, -0.13, -50.0),
    (0.00, 0.19, 90.0),
    (0.00, -0.19, -90.0),
)


@dataclass(frozen=True)
class Geometry:
    """Robot geometry: wheel base, IR mounts [x m, y m, yaw deg], GPS antenna [x, y] m."""

    wheel_base_m: float = field(default=0.33, metadata=_positive("0.33"))
    ir_mounts: tuple[tuple[float, float, float], ...] = field(
        default=_PAPER_MOUNTS_DEG,
        metadata=_check(lambda v: 1 <= len(v) <= 8, "must list 1 to 8 [x, y, yaw_deg] mounts"),
    )
    gps_antenna_m: tuple[float, float] = (0.0, 0.0)

    def ir_mounts_rad(self) -> tuple[tuple[float, float, float], ...]:
        return tuple((x, y, yaw * DEG) for x, y, yaw in self.ir_mounts)


@dataclass(frozen=True)
class Noise:
    """Sensor noise (1-sigma) for the filters: heading filter (ir-grid-mapping eq. 2, 4)
    and pose EKF (ekf-vs-cp eq. 1-4)."""

    encoder_alpha_rad_per_m: float = field(default=3.0 * DEG, metadata=_positive("0.05"))
    encoder_beta: float = field(default=0.1, metadata=_positive("0.1"))
    gyro_gamma: float = field(default=0.02, metadata=_positive("0.02"))
    gyro_arw_rad_per_sqrt_s: float = field(default=0.00026, metadata=_positive("0.00026"))
    wheel_noise_m_per_sqrt_m: float = field(default=0.005, metadata=_positive("0.005"))
    encoder_bias_sigma_rad_per_m: float = field(default=0.03, metadata=_non_negative("0.03"))
    encoder_bias_rad_per_m: float = 0.0
    track_scale_sigma: float = field(default=0.02, metadata=_non_negative("0.02"))
    gyro_scale_sigma: float = field(default=0.005, metadata=_non_negative("0.005"))
    gyro_bias_sigma_radps: float = field(default=0.0017, metadata=_non_negative("0.0017"))
    gyro_bias_walk_radps_per_sqrt_s: float = field(default=3.5e-5, metadata=_non_negative("3.5e-5"))
    gps_uere_m: float = field(default=4.0, metadata=_positive("4.0"))


# -- services ----------------------------------------------------------------------------
@dataclass(frozen=True)
class HeadingService:
    """Encoder + gyro heading filter (fusion.heading); needed by mapping."""

    enabled: bool = True
    bias_min_rest_s: float = field(default=0.5, metadata=_check(lambda v: v >= 0, ">= 0"))


@dataclass(frozen=True)
class PoseService:
    """Pose EKF (fusion.pose_ekf): odometry + gyro + GPS, frame "map"."""

    enabled: bool = True
    use_gps: bool = True
    init_from_gps: bool = False  # true: start where the first GPS fix says, not initial_pose


@dataclass(frozen=True)
class MappingService:
    """IR occupancy grid, optionally with sample-based data association (eq. 7-8).

    The association's acceptance tests were validated with the default six IR mounts
    (on the Intel laser log: never worse than no association in 8 seeds); there, with
    four mounts 2 seeds in 8 were worse, with three 1 in 4, with eight none in 8. With
    another layout, run
    ``bench/ir_real.py DIR --mounts ...`` on a log of the building before relying on
    it (docs/benchmarks.md, "IR mapping on real data")."""

    enabled: bool = True
    resolution_m: float = field(default=0.05, metadata=_positive("0.05"))
    origin_m: tuple[float, float] = (-1.0, -1.0)
    size_m: tuple[float, float] = field(
        default=(12.0, 10.0), metadata=_check(lambda v: v[0] > 0 and v[1] > 0, "both > 0")
    )
    association: bool = True
    samples: int = field(default=200, metadata=_check(lambda v: v >= 10, "must be >= 10"))
    # At the end of a run the association's loop checks are solved as a pose graph and
    # the map rebuilt at its poses, if that draws the walls in no more cells
    # (mapping.loop_graph); false keeps the association's own poses and map.
    pose_graph: bool = True
    publish_every_s: float = field(default=2.0, metadata=_positive("2.0"))
    seed: int = 0
    # The motion filter (mapping.motion_filter): a scan goes into the grid after this
    # much travel, or turn, or time since the last one (a huge value, e.g. 1e9, switches
    # that trigger off); with motion_filter = false every scan goes in.
    motion_filter: bool = True
    min_travel_m: float = field(default=0.05, metadata=_positive("0.05"))
    min_turn_deg: float = field(default=2.0, metadata=_positive("2.0"))
    max_interval_s: float = field(default=1.0, metadata=_positive("1.0"))


@dataclass(frozen=True)
class LocalizationService:
    """Guaranteed CP localization (localization.cp): pose boxes from bounded errors."""

    enabled: bool = True
    publish_every_s: float = field(default=0.5, metadata=_positive("0.5"))
    window: int = field(default=40, metadata=_check(lambda v: 0 <= v <= 1000, "0..1000"))
    wheel_abs_bound_m: float = field(default=0.003, metadata=_positive("0.003"))
    wheel_rel_bound: float = field(default=0.01, metadata=_fraction())
    wheelbase_bound_m: float = field(default=0.01, metadata=_check(lambda v: v >= 0, ">= 0"))
    # 3 sigma per axis of a consumer receiver in open sky, the fake's error model
    # (fakes/world/gps_model.py: bias 1.5 m and white 0.5 m per axis, sqrt(1.5^2 + 0.5^2)
    # = 1.58 m; 3 x 1.58 = 4.74 m); fixes beyond it are what gps_outliers is for.
    gps_bound_m: float = field(default=4.75, metadata=_positive("4.75"))
    gps_outliers: int = field(default=2, metadata=_check(lambda v: v >= 0, ">= 0"))
    gyro_bound_deg: float = field(default=1.0, metadata=_positive("1.0"))
    gyro_drift_bound_degps: float = field(default=0.3, metadata=_check(lambda v: v >= 0, ">= 0"))
    initial_bound_m: float = field(default=0.05, metadata=_check(lambda v: v >= 0, ">= 0"))
    initial_bound_deg: float = field(default=1.0, metadata=_check(lambda v: v >= 0, ">= 0"))
    peer_timeout_s: float = field(default=1.0, metadata=_positive("1.0"))


@dataclass(frozen=True)
class Services:
    heading: HeadingService = field(default_factory=HeadingService)
    pose: PoseService = field(default_factory=PoseService)
    mapping: MappingService = field(default_factory=MappingService)
    localization: LocalizationService = field(default_factory=LocalizationService)


# -- the rest ------------------------------------------------------------------------------
@dataclass(frozen=True)
class ZenohTable:
    """The [zenoh] table; see :class:`hilnav.bus.ZenohSettings` for the meaning. A fleet
    across hosts meets through Zenoh routers (``hilnav router``): mode "client" and the
    routers in ``connect`` (two routers: the second takes over when the first goes)."""

    mode: str = field(default="peer", metadata=_choice("peer", "client", "router"))
    listen: tuple[str, ...] = ("tcp/127.0.0.1:7447",)
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    gossip_scouting: bool = False
    config_file: str = ""  # a native Zenoh JSON5 config as the base
    access_control: dict[str, Any] = field(default_factory=dict)
    tls: dict[str, Any] = field(default_factory=dict)
    usrpwd: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    def settings(self) -> ZenohSettings:
        return ZenohSettings(
            mode=self.mode,
            listen=self.listen,
            connect=self.connect,
            multicast_scouting=self.multicast_scouting,
            gossip_scouting=self.gossip_scouting,
            config_file=self.config_file or None,
            access_control=self.access_control or None,
            tls=self.tls or None,
            usrpwd=self.usrpwd or None,
            extra=dict(self.extra),
        )


@dataclass(frozen=True)
class CmdVel:
    """Velocity commands from the bus: limits, the timeout that stops the robot, and how
    long the service loop may stall before the robot is stopped."""

    timeout_s: float = field(default=0.5, metadata=_positive("0.5"))
    stall_s: float = field(default=0.5, metadata=_positive("0.5"))
    max_linear_mps: float = field(default=0.75, metadata=_positive("0.75"))
    max_angular_radps: float = field(default=1.5, metadata=_positive("1.5"))

    def limits(self) -> CmdVelLimits:
        return CmdVelLimits(
            self.timeout_s, self.stall_s, self.max_linear_mps, self.max_angular_radps
        )


@dataclass(frozen=True)
class Log:
    """MCAP logging: one file per run in ``dir``."""

    enabled: bool = True
    dir: str = "hilnav-logs"
    compression: str = field(default="zstd", metadata=_choice("zstd", "lz4", "none"))
    raw: bool = True  # log the raw bytes of every device


@dataclass(frozen=True)
class Simulation:
    """Emulated devices for ports set to "sim" (started by hilnav run as a subprocess)."""

    plan: str = field(default="office", metadata=_choice("office", "paper_room", "open_field"))
    seed: int = 0
    gps_rate_hz: float = field(default=1.0, metadata=_check(lambda v: 1 <= v <= 10, "1..10"))
    truth_rate_hz: float = field(default=10.0, metadata=_check(lambda v: 0 < v <= 100, "0..100"))
    corrupt: float = field(default=0.0, metadata=_fraction())


@dataclass(frozen=True)
class RobotConfig:
    """Everything about one robot (see the module docstring)."""

    name: str = field(
        default="r1", metadata=_check(_name_ok, "letters, digits, '-' or '_' only (e.g. r1)")
    )
    fleet: tuple[str, ...] = field(
        default=("operator",),
        metadata=_check(lambda v: all(map(_name_ok, v)), "names of letters, digits, - or _"),
    )
    diagnostics_period_s: float = field(default=1.0, metadata=_positive("1.0"))
    initial_pose: tuple[float, float, float] = (1.5, 1.5, 0.0)  # x m, y m, yaw deg in "map"
    devices: Devices = field(default_factory=Devices)
    geometry: Geometry = field(default_factory=Geometry)
    noise: Noise = field(default_factory=Noise)
    services: Services = field(default_factory=Services)
    zenoh: ZenohTable = field(default_factory=ZenohTable)
    cmd_vel: CmdVel = field(default_factory=CmdVel)
    log: Log = field(default_factory=Log)
    simulation: Simulation = field(default_factory=Simulation)
    source: str = field(default="<defaults>", metadata={"internal": True})

    @property
    def simulated(self) -> bool:
        """True when any enabled device is served by the simulation."""
        return any(d.enabled and d.port == "sim" for _, d in self.devices.sections())
