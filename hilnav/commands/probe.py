"""``hilnav probe DEVICE PORT``: connect one driver and print one JSON object per message."""

from __future__ import annotations

import argparse
import json
import math
import signal
import time

from drivers.base import DeviceError
from hilnav.commands.probe_sensors import no_messages, probe_config, register_sensors
from hilnav.devices import DEVICES
from hilnav.errors import CliError
from msgs import RobotInfo, RobotOdometry, to_dict


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "probe",
        help="connect a driver to a port and print its messages as JSON lines",
        description="PORT may be a device path, tcp://HOST:PORT or a file of recorded bytes.",
    )
    dev = p.add_subparsers(dest="device", metavar="DEVICE", required=True)
    a = dev.add_parser("arcos", help="a Pioneer (ARCOS): robot info, then one object per SIP")
    a.add_argument("port")
    a.add_argument("--baud", type=int, default=9600)
    a.add_argument("--drive", metavar="V,W", help="drive at V m/s and W rad/s while probing")
    a.add_argument("--seconds", type=float, default=5.0, help="how long to probe (default 5)")
    a.set_defaults(func=probe_arcos)
    register_sensors(dev)


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
