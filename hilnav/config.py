"""One robot's configuration: a TOML file checked key by key against typed dataclasses.

``load_config(None)`` gives the embedded defaults, a simulated Pioneer 3-DX with every
sensor in the office floor plan (``hilnav/default.toml`` spells the same defaults out as
an example). ``load_config(path)`` reads a TOML file whose tables override those
defaults. Anything wrong (TOML syntax, an unknown key, a wrong type, a value out of
range) raises :class:`ConfigError` with ONE message naming the key, the bad value and
the fix, with a did-you-mean for misspelt keys.

Device ports are a serial device path, ``tcp://host:port``, a file of recorded bytes, or
``sim`` (the matching emulated device of ``[simulation]``, started by ``hilnav run``).
Angles in the file are in degrees (``ir_mounts`` yaw), everything else SI.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivers.irboard import IrBoardConfig
from hilnav.bus import ZenohSettings, check_name
from hilnav.cmdvel import CmdVelLimits
from msgs.typed import TypedReader, hints, join

DEG = math.pi / 180.0


class ConfigError(ValueError):
    """A configuration problem: the message names the key, the bad value and the fix."""


def _check(test: typing.Callable[[Any], bool], problem: str) -> dict[str, Any]:
    return {"check": (test, problem)}


def _positive(eg: str) -> dict[str, Any]:
    return _check(lambda v: v > 0, f"must be > 0 (e.g. {eg})")


def _choice(*options: Any) -> dict[str, Any]:
    return _check(lambda v: v in options, "must be one of " + ", ".join(map(repr, options)))


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
    baud: int = field(default=9600, metadata=_positive("9600"))


@dataclass(frozen=True)
class IrDevice:
    """The IR ADC board: on a serial port (link "serial") or on CAN (link "can")."""

    enabled: bool = True
    link: str = field(default="can", metadata=_choice("serial", "can"))
    port: str = "sim"  # serial link: the port; can link with slcan: the adapter's port
    baud: int = field(default=115200, metadata=_positive("115200"))
    can_interface: str = "slcan"  # python-can interface: slcan, socketcan, virtual, ...
    can_channel: str = ""  # empty: the port (slcan); e.g. can0 for socketcan
    can_bitrate: int = field(default=500_000, metadata=_positive("500000"))
    board_id: int = field(default=1, metadata=_check(lambda v: 0 <= v <= 15, "must be 0..15"))
    rate_hz: int = field(default=20, metadata=_check(lambda v: 1 <= v <= 1000, "must be 1..1000"))
    adc_bits: int = field(default=10, metadata=_choice(10, 12))
    vref_v: float = field(default=5.0, metadata=_positive("5.0"))
    median_window: int = field(default=3, metadata=_check(lambda v: 1 <= v <= 15, "1..15"))


@dataclass(frozen=True)
class GyroDevice:
    """The CruzCore gyro."""

    enabled: bool = True
    port: str = "sim"
    baud: int = field(default=115200, metadata=_positive("115200"))
    rate_hz: int = field(default=100, metadata=_check(lambda v: 1 <= v <= 1000, "1..1000"))


@dataclass(frozen=True)
class GpsDevice:
    """The NMEA GPS; ``datum`` = [lat, lon] degrees of the local east/north origin."""

    enabled: bool = True
    port: str = "sim"
    baud: int = field(default=9600, metadata=_positive("9600"))
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
    """IR occupancy grid, optionally with sample-based data association (eq. 7-8)."""

    enabled: bool = True
    resolution_m: float = field(default=0.05, metadata=_positive("0.05"))
    origin_m: tuple[float, float] = (-1.0, -1.0)
    size_m: tuple[float, float] = field(
        default=(12.0, 10.0), metadata=_check(lambda v: v[0] > 0 and v[1] > 0, "both > 0")
    )
    association: bool = True
    samples: int = field(default=200, metadata=_check(lambda v: v >= 10, "must be >= 10"))
    publish_every_s: float = field(default=2.0, metadata=_positive("2.0"))
    seed: int = 0


@dataclass(frozen=True)
class LocalizationService:
    """Guaranteed CP localization (localization.cp): pose boxes from bounded errors."""

    enabled: bool = True
    publish_every_s: float = field(default=0.5, metadata=_positive("0.5"))
    window: int = field(default=40, metadata=_check(lambda v: 0 <= v <= 1000, "0..1000"))
    wheel_abs_bound_m: float = field(default=0.003, metadata=_positive("0.003"))
    wheel_rel_bound: float = field(default=0.01, metadata=_fraction())
    wheelbase_bound_m: float = field(default=0.01, metadata=_check(lambda v: v >= 0, ">= 0"))
    gps_bound_m: float = field(default=6.0, metadata=_positive("6.0"))
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
    """The [zenoh] table; see :class:`hilnav.bus.ZenohSettings` for the meaning."""

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


# -- loading -------------------------------------------------------------------------------
def _type_word(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_type_word(args[0])}s"
        return f"a list of {len(args)} numbers" if args else "a list"
    if origin is dict or tp is dict:
        return "a table"
    return {float: "number", int: "integer", bool: "boolean (true/false)", str: "string"}.get(
        tp, str(tp)
    )


class _Loader(TypedReader):
    """The config's policy over msgs.typed: ConfigError naming the file, the key, the
    value and the fix; finite floats; unknown keys refused with a did-you-mean; each
    field's ``check`` metadata run; ``internal`` fields not settable from the file."""

    error = ConfigError

    def __init__(self, src: str) -> None:
        self.src = src

    def bad(self, path: str, value: Any, expect: str) -> ConfigError:
        return ConfigError(f"{self.src}: {path} = {value!r}: expected {expect}")

    def fail(self, kind: str, tp: Any, value: Any, path: str) -> ConfigError:
        if kind == "list":
            return self.bad(
                path, value, _type_word(tp) + f", e.g. {path.rsplit('.', 1)[-1]} = [...]"
            )
        if kind == "length":
            return self.bad(path, value, f"{len(typing.get_args(tp))} values, got {len(value)}")
        if kind == "mapping":
            return self.bad(path, value, "a table")
        if kind == "literal":
            return self.bad(path, value, "one of " + ", ".join(map(repr, typing.get_args(tp))))
        return self.bad(path, value, _type_word(tp))

    def scalar(self, tp: Any, value: Any, path: str) -> Any:
        if tp is float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise self.bad(path, value, "a number")
            if not math.isfinite(value):
                raise self.bad(path, value, "a finite number")
            return float(value)
        if tp is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.bad(path, value, "an integer")
            return value
        if tp is bool:
            if not isinstance(value, bool):
                raise self.bad(path, value, "true or false")
            return value
        if tp is str:
            if not isinstance(value, str):
                raise self.bad(path, value, 'a string in quotes, e.g. "..."')
            return value
        raise self.bad(path, value, str(tp))  # pragma: no cover - a schema bug

    def record(self, cls: type, value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            raise self.bad(path, value, f"a table, e.g. [{path}] on its own line")
        fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
        for k in value:
            if k not in fields:
                close = difflib.get_close_matches(k, list(fields), n=1, cutoff=0.6)
                hint = (
                    f"did you mean {join(path, close[0])}?"
                    if close
                    else f"known keys{' of [' + path + ']' if path else ''}: {', '.join(fields)}"
                )
                raise ConfigError(f"{self.src}: unknown key {join(path, k)!r}; {hint}")
        kwargs: dict[str, Any] = {}
        for name, f in fields.items():
            if name in value:
                kwargs[name] = self._field(f, hints(cls)[name], value[name], join(path, name))
        return cls(**kwargs)

    def _field(self, f: dataclasses.Field, tp: Any, value: Any, full: str) -> Any:
        """One field: read, with the default as the example of a fix, then checked."""
        if dataclasses.is_dataclass(tp):
            return self.record(tp, value, full)
        try:
            conv = self.read(tp, value, full)
        except ConfigError as exc:
            d = f.default
            if isinstance(d, bool | int | float | str) and "e.g." not in str(exc):
                toml = str(d).lower() if isinstance(d, bool) else repr(d).replace("'", '"')
                raise ConfigError(f"{exc}, e.g. {f.name} = {toml}") from None
            raise
        chk = f.metadata.get("check")
        if chk is not None:
            test, problem = chk
            try:
                ok = bool(test(conv))
            except (TypeError, ValueError, IndexError):
                ok = False
            if not ok:
                raise ConfigError(f"{self.src}: {full} = {value!r}: {problem}")
        return conv


def _build(cls: type, data: dict[str, Any], path: str, src: str) -> Any:
    """``cls`` from the TOML table ``data`` at ``path`` of the file ``src``."""
    return _Loader(src).record(cls, data, path)


def _cross_checks(cfg: RobotConfig, src: str) -> None:
    d = cfg.devices
    for dev, dc in d.sections():
        if dc.enabled and not dc.port and not (dev == "ir" and dc.link == "can" and dc.can_channel):
            raise ConfigError(
                f"{src}: devices.{dev}.port = '': give the port (e.g. /dev/ttyUSB0, "
                'tcp://127.0.0.1:8101) or "sim", or set devices.' + dev + ".enabled = false"
            )
    if cfg.services.mapping.enabled and not cfg.services.heading.enabled:
        raise ConfigError(
            f"{src}: services.mapping.enabled = true needs services.heading.enabled = true "
            "(the map is drawn with the fused heading); enable heading or disable mapping"
        )
    if cfg.zenoh.config_file and not Path(cfg.zenoh.config_file).is_file():
        raise ConfigError(
            f"{src}: zenoh.config_file = {cfg.zenoh.config_file!r}: no such file; give the "
            "path of a Zenoh JSON5 config or remove the key"
        )
    eps = [(f"zenoh.listen[{i}]", e) for i, e in enumerate(cfg.zenoh.listen)]
    eps += [(f"zenoh.connect[{i}]", e) for i, e in enumerate(cfg.zenoh.connect)]
    for where, ep in eps:
        proto, sep, rest = ep.partition("/")
        if (
            not sep
            or not rest
            or proto not in ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream")
        ):
            raise ConfigError(
                f'{src}: {where} = {ep!r}: expected PROTO/ADDRESS:PORT, e.g. "tcp/127.0.0.1:7447"'
            )


def parse_config(data: dict[str, Any], source: str = "<config>") -> RobotConfig:
    """A RobotConfig from already-parsed TOML data (defaults for what it leaves out)."""
    cfg = _build(RobotConfig, data, "", source)
    cfg = dataclasses.replace(cfg, source=source)
    _cross_checks(cfg, source)
    return cfg


def load_config(path: str | Path | None) -> RobotConfig:
    """The embedded defaults (None) or a TOML file over them; ConfigError if wrong."""
    if path is None:
        return RobotConfig()
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(
            f"{p}: no such config file; write one starting from {default_toml_path()} "
            "or run without --config for the simulated defaults"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(
            f"{p}: not valid TOML: {exc}; check quotes around strings and [table] headers"
        ) from None
    return parse_config(data, str(p))


def config_data(cfg: RobotConfig) -> dict[str, Any]:
    """The config as plain TOML/JSON-able data: ``parse_config(config_data(c))`` gives
    back ``c`` (this is how the daemon hands its resolved config to ``hilnav fake``)."""

    def plain(v: Any) -> Any:
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    data = plain(dataclasses.asdict(cfg))
    data.pop("source", None)
    return data


def default_toml_path() -> Path:
    """The example config shipped with the package (same values as the defaults)."""
    return Path(__file__).with_name("default.toml")


def summary(cfg: RobotConfig) -> str:
    """A few lines saying what the config will run (for ``hilnav config check``)."""
    d = cfg.devices
    lines = [f"robot {cfg.name} (config {cfg.source})"]
    for name, dc in d.sections():
        if not dc.enabled:
            lines.append(f"  {name:6s} off")
            continue
        where = dc.port
        if name == "ir" and dc.link == "can":
            where = f"CAN {dc.can_interface}:{dc.can_channel or dc.port}"
        lines.append(f"  {name:6s} {where} @ {dc.baud} baud")
    sv = cfg.services
    on = [n for n in ("heading", "pose", "mapping", "localization") if getattr(sv, n).enabled]
    lines.append(f"  services: {', '.join(on) or 'none'}")
    z = cfg.zenoh
    lines.append(
        f"  zenoh {z.mode}: listen {list(z.listen)} connect {list(z.connect)} "
        f"multicast scouting {'on' if z.multicast_scouting else 'off'}"
    )
    lines.append(f"  fleet: {', '.join(cfg.fleet) or '(only itself)'}")
    lines.append(f"  log: {cfg.log.dir if cfg.log.enabled else 'off'}")
    return "\n".join(lines)


def ir_board_config(cfg: RobotConfig) -> IrBoardConfig:
    """The IR ADC board settings of a robot config, as the IR driver and codecs take them."""
    ir = cfg.devices.ir
    return IrBoardConfig(
        board_id=ir.board_id,
        adc_bits=ir.adc_bits,
        vref_v=ir.vref_v,
        rate_hz=ir.rate_hz,
        mounts=cfg.geometry.ir_mounts_rad(),
        median_window=ir.median_window,
    )
