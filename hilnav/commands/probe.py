"""``hilnav probe DEVICE PORT``: connect one driver and print one JSON object per message."""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import time
from typing import TYPE_CHECKING, Any

from hilnav.commands.probe_sensors import no_messages, probe_config, register_sensors
from hilnav.errors import CliError

if TYPE_CHECKING:
    from msgs import RobotOdometry


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "probe",
        help="connect a driver to a port and print its messages as JSON lines",
        description="PORT is a device path, a pyserial URL (socket://HOST:PORT, tcp://HOST:PORT, "
        "rfc2217://HOST:PORT, spy:///dev/ttyUSB0, hwgrep://VID:PID) or a file of recorded "
        "bytes; for an IR board on CAN it is INTERFACE:CHANNEL (slcan:/dev/ttyACM0, "
        "socketcan:can0, virtual:NAME). `hilnav probe --list` lists the serial ports.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument(
        "--list",
        action="store_true",
        help="list the serial ports (device, VID:PID, description, /dev/serial/by-id links) "
        "and guess which device each is",
    )
    p.set_defaults(func=list_ports)
    dev = p.add_subparsers(dest="device", metavar="DEVICE")
    a = dev.add_parser("arcos", help="a Pioneer (ARCOS): robot info, then one object per SIP")
    a.add_argument("port", help="the Pioneer's serial port, a pyserial URL or a file of bytes")
    a.add_argument(
        "--baud",
        type=int,
        default=9600,
        help="serial speed (ignored for files and URLs that have none)",
    )
    a.add_argument("--drive", metavar="V,W", help="drive at V m/s and W rad/s while probing")
    a.add_argument("--seconds", type=float, default=5.0, help="how long to probe (default 5)")
    a.set_defaults(func=probe_arcos)
    register_sensors(dev)


def list_ports(args: argparse.Namespace) -> int:
    """``hilnav probe --list``: one line per serial port, with a guess of its device."""
    if not args.list:
        raise CliError("give a DEVICE and its PORT (hilnav probe arcos /dev/ttyUSB0), or --list")
    from serial.tools import list_ports as lp

    by_id = _by_id_links()
    ports = sorted(lp.comports(), key=lambda p: p.device)
    for p in ports:
        print(json.dumps(port_row(p, by_id)), flush=True)
    if not ports:
        print("no serial ports found", file=sys.stderr)
    return 0


def _by_id_links(folder: str = "/dev/serial/by-id") -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    if os.path.isdir(folder):
        for name in sorted(os.listdir(folder)):
            link = os.path.join(folder, name)
            out.setdefault(os.path.realpath(link), []).append(link)
    return out


def port_row(p: Any, by_id: dict[str, list[str]]) -> dict[str, Any]:
    """What ``--list`` prints for one ``serial.tools.list_ports`` entry."""
    from hilnav.devices import guess_device

    usb = f"{p.vid:04x}:{p.pid:04x}" if p.vid is not None and p.pid is not None else None
    return {
        "port": p.device,
        "usb": usb,
        "description": p.description,
        "serial_number": p.serial_number,
        "by_id": by_id.get(os.path.realpath(p.device), []),
        "guess": guess_device(p.vid, p.pid, f"{p.description} {p.manufacturer or ''}"),
    }


def _parse_drive(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        v, w = (float(x) for x in text.split(","))
    except ValueError:
        raise CliError(f"--drive {text!r}: expected V,W in m/s and rad/s, e.g. 0.2,0.1") from None
    if not (math.isfinite(v) and math.isfinite(w)):
        raise CliError(f"--drive {text!r}: values must be finite")
    return v, w


def sip_json(m: RobotOdometry) -> dict:
    return {
        "stamp_ns": m.stamp_ns,
        "x": round(m.pose.x, 4),
        "y": round(m.pose.y, 4),
        "th": round(m.pose.theta, 5),
        "left_mps": m.left_vel_mps,
        "right_mps": m.right_vel_mps,
        "v_mps": m.linear_vel_mps,
        "w_radps": round(m.angular_vel_radps, 5),
        "battery_v": m.battery_v,
        "moving": m.moving,
        "motors_enabled": m.motors_enabled,
        "estop": m.estop,
        "stall": [m.left_stall, m.right_stall],
        "bumpers": {"front": m.front_bumpers, "rear": m.rear_bumpers},
    }


def probe_arcos(args: argparse.Namespace) -> int:
    from drivers.base import DeviceError
    from hilnav.devices import DEVICES
    from msgs import RobotInfo, RobotOdometry, to_dict

    drive = _parse_drive(args.drive)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    cfg = probe_config("arcos", {"port": args.port, "baud": args.baud})
    driver = DEVICES["arcos"].driver(cfg, None)
    try:
        info = driver.open()
    except DeviceError as exc:
        raise CliError(str(exc)) from None
    if info is not None:
        print(json.dumps({"robot": to_dict(info)}), flush=True)
    deadline = time.monotonic() + args.seconds
    sips = 0
    try:
        while time.monotonic() < deadline and not stop and not driver.eof:
            if drive is not None:
                driver.set_velocity(*drive)
            for m in driver.read(0.2):
                if isinstance(m, RobotOdometry):
                    sips += 1
                    print(json.dumps(sip_json(m)), flush=True)
                elif isinstance(m, RobotInfo) and m is not info:
                    print(json.dumps({"robot": to_dict(m)}), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        ended = driver.eof
        if drive is not None:
            driver.stop()
        driver.close()
    if sips == 0 and ended:
        raise CliError(no_messages(args.port, driver))
    return 0
