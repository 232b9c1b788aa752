"""The device table: everything hilnav knows per device, in one entry each.

Like python-can's interface registry, a device is one :class:`Device` entry in
:data:`DEVICES`: its config section (``[devices.<name>]`` of the robot TOML, a field of
:class:`hilnav.config.Devices`), the messages its driver yields (their topics are in
:mod:`hilnav.topics`), and three factories from a :class:`~hilnav.config.RobotConfig`:

- ``driver(cfg, on_raw, **options)``: the driver the daemon and ``hilnav probe`` run
  (``options``: driver settings a robot config does not hold, e.g. probe's
  ``--no-reset``);
- ``codec(cfg)``: the bytes -> messages codec ``hilnav replay`` rebuilds messages with
  from the logged raw bytes (``codec.feed(data, stamp_ns) -> [msg]``, one raw record at
  a time; the IR board on CAN logs one frame per record,
  :func:`drivers.irboard.canframe.pack_raw_frame`);
- ``emulator(cfg, knobs)``: the emulated twin ``hilnav fake`` serves (knobs: the fault
  and test settings that are not part of a robot's config, :class:`FakeKnobs`);

and ``attach(section, ports)``, which points a "sim" port at the port the fake printed;
``usb_ids``/``usb_words`` let ``hilnav probe --list`` guess which device a USB port is.
Adding a fifth device is one entry here plus its config section.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from hilnav.config import RobotConfig, ir_board_config
from msgs import GpsFix, GpsSky, GyroSample, IrScan, RobotInfo, RobotOdometry

RawHook = Callable[[bytes, int], None] | None


@dataclass(frozen=True)
class FakeKnobs:
    """Emulator settings that are not part of a robot's config: faults and test links."""

    link_dir: str | None = None
    baud: int | None = None  # pace the Pioneer's output like a real link
    drop: float = 0.0  # fraction of Pioneer packets dropped
    vanish_after: float | None = None  # the Pioneer port disappears after S s ...
    vanish_for: float = 2.0  # ... for S s
    replay: dict[str, str] = field(default_factory=dict)  # device -> recorded file
    replay_fast: bool = False
    ir_link: str = ""  # "python-can": the IR board on an in-process virtual CAN bus


@dataclass(frozen=True)
class Device:
    name: str
    doc: str
    messages: tuple[type, ...]
    driver: Callable[..., Any]  # (cfg, on_raw, **driver options) -> driver
    codec: Callable[[RobotConfig], Any]
    emulator: Callable[[RobotConfig, FakeKnobs], Any]
    attach: Callable[[Any, dict[str, str]], Any]
    usb_ids: tuple[str, ...] = ()  # "VID:PID" of adapters that are this device
    usb_words: tuple[str, ...] = ()  # words of a USB description that name it

    def section(self, cfg: RobotConfig) -> Any:
        return getattr(cfg.devices, self.name)


def _port(key: str) -> Callable[[Any, dict[str, str]], Any]:
    def attach(section: Any, ports: dict[str, str]) -> Any:
        return dataclasses.replace(section, port=ports[key]) if key in ports else section

    return attach


# -- arcos -------------------------------------------------------------------------------
def _arcos_driver(cfg: RobotConfig, on_raw: RawHook, **extra: Any) -> Any:
    from drivers.arcos.driver import ArcosDriver, ArcosOptions

    a = cfg.devices.arcos
    return ArcosDriver(a.port, ArcosOptions(baud=a.baud), **{"on_raw": on_raw, **extra})


def _arcos_codec(cfg: RobotConfig) -> Any:
    from drivers.arcos.codec import ArcosCodec

    return ArcosCodec()


def _arcos_emulator(cfg: RobotConfig, knobs: FakeKnobs) -> Any:
    from fakes.pioneer import PioneerEmulator, PioneerFaults
    from fakes.pioneer_config import PioneerConfig

    faults = PioneerFaults(cfg.simulation.corrupt, knobs.drop, knobs.vanish_after, knobs.vanish_for)
    pc = PioneerConfig(name=cfg.name, baud=knobs.baud)
    return PioneerEmulator(cfg.name, pc, faults, seed=cfg.simulation.seed)


# -- ir ------------------------------------------------------------------------------------
def _ir_driver(cfg: RobotConfig, on_raw: RawHook, **extra: Any) -> Any:
    from drivers.irboard.driver import IrCanDriver, IrSerialDriver

    ir = cfg.devices.ir
    board = ir_board_config(cfg)
    if ir.link == "can":
        chan = ir.can_channel or ir.port
        kw = {"bitrate": ir.can_bitrate, "on_raw": on_raw, "bus_kwargs": ir.can, **extra}
        return IrCanDriver(ir.can_interface, chan, board, **kw)
    return IrSerialDriver(ir.port, board, **{"baud": ir.baud, "on_raw": on_raw, **extra})


def _ir_codec(cfg: RobotConfig) -> Any:
    from drivers.irboard.codec import IrCanCodec, IrSerialCodec

    board = ir_board_config(cfg)
    return IrCanCodec(board) if cfg.devices.ir.link == "can" else IrSerialCodec(board)


def _ir_emulator(cfg: RobotConfig, knobs: FakeKnobs) -> Any:
    from fakes.irboard import IrBoardEmulator

    link = knobs.ir_link or ("slcan" if cfg.devices.ir.link == "can" else "serial")
    return IrBoardEmulator(
        cfg.name,
        ir_board_config(cfg),
        link=link,
        can_channel=f"hilnav-{cfg.name}",
        seed=cfg.simulation.seed + 1,
    )


def _ir_attach(ir: Any, ports: dict[str, str]) -> Any:
    if ir.link == "can" and "ir_can" in ports:
        iface, _, chan = ports["ir_can"].partition(":")
        return dataclasses.replace(ir, port=chan, can_interface=iface, can_channel=chan)
    if ir.link == "serial" and "ir" in ports:
        return dataclasses.replace(ir, port=ports["ir"])
    return ir


# -- gyro ----------------------------------------------------------------------------------
def _gyro_driver(cfg: RobotConfig, on_raw: RawHook, **extra: Any) -> Any:
    from drivers.cruzcore_driver import CruzCoreDriver

    g = cfg.devices.gyro
    return CruzCoreDriver(
        g.port, **{"baud": g.baud, "rate_hz": g.rate_hz, "on_raw": on_raw, **extra}
    )


def _gyro_codec(cfg: RobotConfig) -> Any:
    from drivers.cruzcore import CruzCoreCodec

    return CruzCoreCodec(cfg.devices.gyro.rate_hz)  # stamps as the driver's


def _gyro_emulator(cfg: RobotConfig, knobs: FakeKnobs) -> Any:
    from fakes.gyro import GyroEmulator
    from fakes.world.gyro_model import GyroErrorModel

    seed = cfg.simulation.seed + 2
    return GyroEmulator(cfg.name, cfg.devices.gyro.rate_hz, GyroErrorModel(seed=seed))


# -- gps -----------------------------------------------------------------------------------
def _gps_driver(cfg: RobotConfig, on_raw: RawHook, **extra: Any) -> Any:
    from drivers.nmea.driver import NmeaDriver
    from drivers.nmea.local import Datum

    g = cfg.devices.gps
    kw = {"baud": g.baud, "datum": Datum(*g.datum), "on_raw": on_raw, **extra}
    return NmeaDriver(g.port, **kw)


def _gps_codec(cfg: RobotConfig) -> Any:
    from drivers.nmea.codec import NmeaCodec
    from drivers.nmea.local import Datum

    return NmeaCodec(datum=Datum(*cfg.devices.gps.datum))


def _gps_emulator(cfg: RobotConfig, knobs: FakeKnobs) -> Any:
    from drivers.nmea.local import Datum
    from fakes.gps import GpsEmulator, NmeaReplayEmulator
    from fakes.world.gps_model import GpsErrorModel

    if "gps" in knobs.replay:
        return NmeaReplayEmulator(knobs.replay["gps"], fast=knobs.replay_fast)
    return GpsEmulator(
        cfg.name,
        cfg.simulation.gps_rate_hz,
        GpsErrorModel(seed=cfg.simulation.seed + 3),
        datum=Datum(*cfg.devices.gps.datum),
    )


_TABLE = (
    Device("arcos", "Pioneer 3-DX base (ARCOS)", (RobotOdometry, RobotInfo),
           _arcos_driver, _arcos_codec, _arcos_emulator, _port("arcos")),
    Device("ir", "Sharp GP2Y0A710K IR sensors behind an ADC board (serial or CAN)", (IrScan,),
           _ir_driver, _ir_codec, _ir_emulator, _ir_attach,
           # slcan adapters for the board on CAN: CANable (slcan firmware), Lawicel CANUSB
           usb_ids=("16d0:117e", "0403:ffa8"), usb_words=("canable", "slcan", "can adapter")),
    Device("gyro", "CruzCore gyro", (GyroSample,),
           _gyro_driver, _gyro_codec, _gyro_emulator, _port("gyro")),
    Device("gps", "NMEA GPS receiver", (GpsFix, GpsSky),
           _gps_driver, _gps_codec, _gps_emulator, _port("gps"),
           # u-blox receivers (5 to 9), and words receivers put in their USB description
           usb_ids=("1546:01a5", "1546:01a6", "1546:01a7", "1546:01a8", "1546:01a9"),
           usb_words=("gps", "gnss", "u-blox")),
)  # fmt: skip

DEVICES: dict[str, Device] = {d.name: d for d in _TABLE}


def enabled(cfg: RobotConfig, sim_only: bool = False) -> list[Device]:
    """The devices a config enables (only those whose port is "sim" if ``sim_only``)."""
    out = []
    for d in _TABLE:
        sec = d.section(cfg)
        if sec.enabled and (not sim_only or sec.port == "sim"):
            out.append(d)
    return out


def make_drivers(cfg: RobotConfig, on_raw: Callable[[str], RawHook]) -> dict[str, Any]:
    """One driver per enabled device; ``on_raw(device)`` gives each its raw-bytes hook."""
    return {d.name: d.driver(cfg, on_raw(d.name)) for d in enabled(cfg)}


def make_codecs(cfg: RobotConfig) -> dict[str, Any]:
    """One codec per device, to rebuild its messages from logged raw bytes."""
    return {d.name: d.codec(cfg) for d in _TABLE}


def with_fake_ports(cfg: RobotConfig, ports: dict[str, str]) -> RobotConfig:
    """A copy with the "sim" ports replaced by the ones ``hilnav fake`` printed."""
    changes = {}
    for d in _TABLE:
        sec = d.section(cfg)
        if sec.port == "sim":
            changes[d.name] = d.attach(sec, ports)
    return dataclasses.replace(cfg, devices=dataclasses.replace(cfg.devices, **changes))


# USB-serial bridges any of the serial devices may sit behind (FTDI, Prolific, CP210x, CH340).
USB_SERIAL_IDS = ("0403:6001", "0403:6015", "067b:2303", "10c4:ea60", "1a86:7523")


def guess_device(vid: int | None, pid: int | None, description: str = "") -> str:
    """Which device a USB port probably is, from its IDs and description ("" if unknown)."""
    usb = f"{vid:04x}:{pid:04x}" if vid is not None and pid is not None else ""
    text = description.lower()
    for d in _TABLE:
        if usb in d.usb_ids or any(w in text for w in d.usb_words):
            return d.name
    if usb in USB_SERIAL_IDS:
        serial_ones = ", ".join(n for n in DEVICES if n != "ir")
        return f"a USB-serial adapter ({serial_ones} or ir on serial)"
    return ""
