"""``hilnav probe ir|gyro|gps PORT``: the sensor drivers' messages as JSON lines.

``hilnav probe gps PORT --json`` prints gpsd's objects instead (``{"class":"TPV",...}``,
SKY, GST: :mod:`drivers.nmea.gpsd_json`), one per line.

PORT is a device path, ``tcp://HOST:PORT`` or a file of recorded bytes; for an IR board on
CAN it is ``INTERFACE:CHANNEL`` (``slcan:/dev/ttyACM0``, ``socketcan:can0``,
``virtual:NAME``).
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import time
from typing import TYPE_CHECKING, Any

from hilnav.errors import CliError

if TYPE_CHECKING:
    from hilnav.config import RobotConfig
    from msgs import GpsFix


def register_sensors(dev: argparse._SubParsersAction) -> None:
    """Add ``ir``, ``gyro`` and ``gps`` under ``hilnav probe``."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("port", help="device path, tcp://HOST:PORT or a file of recorded bytes")
    common.add_argument("--seconds", type=float, default=5.0, help="how long (default 5)")
    common.add_argument("--count", type=int, default=None, help="stop after N messages")

    ir = dev.add_parser("ir", parents=[common], help="an IR ADC board: one object per scan")
    ir.add_argument(
        "--baud",
        type=int,
        default=115200,
        help="serial speed (ignored for files and URLs that have none)",
    )
    ir.add_argument("--board", type=int, default=1, help="board id (default 1)")
    ir.add_argument("--bits", type=int, default=10, choices=(10, 12), help="ADC resolution")
    ir.add_argument("--vref", type=float, default=5.0, help="ADC reference voltage")
    ir.add_argument("--channels", type=int, default=6, help="number of sensors (default 6)")
    ir.add_argument("--rate", type=int, default=20, help="sample rate to request (Hz)")
    ir.add_argument("--median", type=int, default=1, help="median over N samples")
    ir.add_argument("--bitrate", type=int, default=500_000, help="CAN bit rate")
    ir.set_defaults(func=probe_ir)

    gy = dev.add_parser("gyro", parents=[common], help="a CruzCore gyro: one object per packet")
    gy.add_argument(
        "--baud",
        type=int,
        default=115200,
        help="serial speed (ignored for files and URLs that have none)",
    )
    gy.add_argument("--rate", type=int, default=None, help="packet rate to request (Hz)")
    gy.add_argument("--no-reset", action="store_true", help="do not re-zero the angle")
    gy.set_defaults(func=probe_gyro)

    gp = dev.add_parser("gps", parents=[common], help="an NMEA GPS: one object per fix and per sky")
    gp.add_argument(
        "--baud",
        type=int,
        default=9600,
        help="serial speed (ignored for files and URLs that have none)",
    )
    gp.add_argument("--datum", metavar="LAT,LON", help="origin of east/north (default first fix)")
    gp.add_argument(
        "--no-checksum-ok",
        action="store_true",
        help="also accept sentences that carry no *hh checksum (some old receivers)",
    )
    gp.add_argument(
        "--json",
        dest="gpsd_json",
        action="store_true",
        help="gpsd's JSON objects (TPV, SKY, GST) with gpsd's names and units",
    )
    gp.set_defaults(func=probe_gps)


def _clean(v: Any) -> Any:
    if isinstance(v, float):
        return None if not math.isfinite(v) else round(v, 9)
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    return v


def gps_json(f: GpsFix) -> dict[str, Any]:
    from msgs import to_dict

    d = to_dict(f)
    out = {
        "time": f.time_utc or None,
        "lat": f.lat_deg,
        "lon": f.lon_deg,
        "alt": f.alt_msl_m,
        "mode": f.mode,
    }
    for k, v in d.items():
        if k not in ("time_utc", "lat_deg", "lon_deg", "alt_msl_m", "mode"):
            out[k] = v
    return _clean(out)


def _json(m: Any) -> list[dict[str, Any]]:
    from msgs import GpsFix, GpsSky, GyroSample, IrScan, to_dict

    if isinstance(m, GpsFix):
        return [gps_json(m)]
    if isinstance(m, (GyroSample, IrScan, GpsSky)):
        return [_clean(to_dict(m))]
    return []


def _loop(driver: Any, args: argparse.Namespace) -> int:
    from drivers.base import DeviceError

    gpsd = getattr(args, "gpsd_json", False)
    as_json = _json
    if gpsd:
        from drivers.nmea.gpsd_json import gpsd_objects as as_json
    seps = (",", ":") if gpsd else None  # gpsd's compact form
    stop: list[int] = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    try:
        driver.open()
    except DeviceError as exc:
        raise CliError(str(exc)) from None
    n, ended = 0, False
    deadline = time.monotonic() + args.seconds
    try:
        while time.monotonic() < deadline and not stop:
            msgs = driver.read(0.2)
            for m in msgs:
                for obj in as_json(m):
                    print(json.dumps(obj, separators=seps), flush=True)
                    n += 1
                    if args.count is not None and n >= args.count:
                        return 0
            if getattr(driver, "eof", False) and not msgs:
                ended = True
                break
    except KeyboardInterrupt:
        pass
    finally:
        driver.close()
    if n == 0 and ended:
        raise CliError(no_messages(args.port, driver))
    return 0


def no_messages(port: str, driver: Any) -> str:
    """The error for a recorded file that held nothing the device's codec could decode."""
    s = driver.codec.stats
    return (
        f"{port}: no {driver.device} messages in this file ({s.bytes_skipped} bytes skipped, "
        f"{s.bad_checksums} bad checksums); is it a recording of this device?"
    )


def probe_ir(args: argparse.Namespace) -> int:
    from hilnav.config import Geometry
    from hilnav.devices import DEVICES

    if not 1 <= args.channels <= 8:
        raise CliError(f"--channels {args.channels}: an IR board has 1 to 8 channels")
    mounts = [list(m) for m in Geometry().ir_mounts[: args.channels]]
    mounts += [[0.0, 0.0, 0.0]] * max(0, args.channels - len(mounts))
    ir: dict[str, Any] = {
        "port": args.port,
        "baud": args.baud,
        "board_id": args.board,
        "adc_bits": args.bits,
        "vref_v": args.vref,
        "rate_hz": args.rate,
        "median_window": args.median,
        "can_bitrate": args.bitrate,
        "link": "serial",
    }
    iface, sep, channel = args.port.partition(":")
    if sep and iface in can_interfaces():
        ir.update(link="can", can_interface=iface, can_channel=channel, port=channel)
    cfg = probe_config("ir", ir, geometry={"ir_mounts": mounts})
    return _loop(DEVICES["ir"].driver(cfg, None), args)


def probe_gyro(args: argparse.Namespace) -> int:
    from hilnav.devices import DEVICES

    cfg = probe_config("gyro", {"port": args.port, "baud": args.baud})
    extra = {"rate_hz": args.rate, "reset_on_open": not args.no_reset}
    return _loop(DEVICES["gyro"].driver(cfg, None, **extra), args)


def probe_gps(args: argparse.Namespace) -> int:
    from drivers.nmea import Datum
    from hilnav.devices import DEVICES

    datum = None
    if args.datum:
        try:
            lat, lon = (float(x) for x in args.datum.split(","))
        except ValueError:
            raise CliError(f"--datum {args.datum!r}: expected LAT,LON in degrees") from None
        datum = Datum(lat, lon)
    cfg = probe_config("gps", {"port": args.port, "baud": args.baud})
    extra = {"datum": datum, "require_checksum": not args.no_checksum_ok}
    return _loop(DEVICES["gps"].driver(cfg, None, **extra), args)


def can_interfaces() -> frozenset[str]:
    """python-can's interface names (its own registry, plugins included)."""
    import can

    return frozenset(can.interfaces.VALID_INTERFACES)


def probe_config(device: str, section: dict[str, Any], **tables: Any) -> RobotConfig:
    """A robot config holding one device's settings from the command line (checked as a
    config file is: a bad value names its key)."""
    from hilnav.config import ConfigError, parse_config

    try:
        return parse_config({"devices": {device: section}, **tables}, "the command line")
    except ConfigError as exc:
        raise CliError(str(exc)) from None
