"""``hilnav fake``: start the emulated devices of one robot and print their ports as JSON."""

from __future__ import annotations

import argparse
import dataclasses
import json
import signal
import sys
import threading
from typing import TYPE_CHECKING

from hilnav.errors import CliError

if TYPE_CHECKING:
    from hilnav.config import RobotConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fake",
        help="emulated devices on ptys, driven by a simulated world",
        description="Start the emulated devices of one simulated robot. Prints ONE JSON line "
        'mapping device names to port paths (e.g. {"arcos": "/tmp/hilnav-fake-x/arcos"}) once '
        "they are ready, then runs until SIGINT/SIGTERM or --duration. The robot (name, wheel "
        "base, IR board and mounts, rates, GPS datum, [simulation]) comes from --config or "
        "the defaults; the options below override it.",
    )
    p.add_argument(
        "--config",
        help='robot TOML file, or "-": the resolved config as one JSON line on stdin, after '
        "which the fake exits when stdin closes (how hilnav run starts it: it dies with "
        "its parent)",
    )
    p.add_argument("--seed", type=int, default=None, help="seed of every random process [0]")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    p.add_argument("--plan", default=None, help="floor plan: paper_room, office, open_field")
    p.add_argument("--robot", default=None, help="robot name in the world [r1]")
    p.add_argument("--link-dir", help="directory for the stable port links (default: a temp dir)")
    p.add_argument("--baud", type=int, default=None, help="pace the Pioneer's output at this baud")
    p.add_argument(
        "--corrupt", type=float, default=None, help="fraction of Pioneer bytes corrupted"
    )
    p.add_argument("--drop", type=float, default=0.0, help="fraction of Pioneer packets dropped")
    p.add_argument(
        "--vanish-after", type=float, default=None, help="the Pioneer port vanishes after S s"
    )
    p.add_argument("--vanish-for", type=float, default=2.0, help="... and comes back after S s")
    p.add_argument(
        "--replay",
        action="append",
        default=[],
        metavar="DEVICE=FILE",
        help="serve a recorded log instead of a simulated device (e.g. gps=nmea.log)",
    )
    p.add_argument(
        "--replay-fast",
        action="store_true",
        help="serve a replayed log as fast as the reader takes it (default: its own pace)",
    )
    p.add_argument(
        "--ir-link",
        default=None,
        choices=("serial", "slcan", "python-can"),
        help="IR board on its serial port, or on CAN: behind an emulated slcan adapter "
        "(slcan) or on a python-can bus (python-can) (default: the config's "
        "devices.ir.link; serial without --config)",
    )
    p.add_argument("--ir-rate", type=int, default=None, help="IR board samples per second [20]")
    p.add_argument("--gyro-rate", type=int, default=None, help="gyro packets per second [100]")
    p.add_argument("--gps-rate", type=float, default=None, help="GPS epochs per second (1-10)")
    p.add_argument(
        "--devices",
        default=None,
        help="comma-separated devices to emulate (default: those the config enables)",
    )
    p.add_argument(
        "--zenoh-connect",
        default=None,
        metavar="ENDPOINT",
        help="publish the ground truth on hilnav/<robot>/truth through a Zenoh peer "
        "connected to ENDPOINT (e.g. tcp/127.0.0.1:7447; multicast scouting off)",
    )
    p.add_argument("--truth-rate", type=float, default=None, help="ground-truth messages per s")
    p.set_defaults(func=run)


def _config(args: argparse.Namespace) -> RobotConfig:
    """The robot config: the file, the JSON line on stdin, or the defaults."""
    from hilnav.config import ConfigError, load_config, parse_config

    try:
        if args.config == "-":
            line = sys.stdin.readline()
            try:
                data = json.loads(line)
            except ValueError:
                raise CliError(
                    "--config -: expected the config as one JSON line on stdin"
                ) from None
            return parse_config(data, "<stdin>")
        return load_config(args.config)
    except ConfigError as exc:
        raise CliError(f"--config {args.config}: {exc}") from None


def _watch_stdin(done: threading.Event) -> None:
    """Stop when the parent's end of stdin closes (the parent died or stopped us)."""

    def watch() -> None:
        while sys.stdin.readline():
            pass
        done.set()

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def run(args: argparse.Namespace) -> int:
    from hilnav.devices import FakeKnobs
    from hilnav.fakeset import build_fakes, override

    replay = {}
    for item in args.replay:
        dev, sep, path = item.partition("=")
        if not sep or not path:
            raise CliError(f"--replay {item!r}: expected DEVICE=FILE, e.g. gps=recorded.nmea")
        replay[dev] = path
    cfg = override(
        _config(args),
        robot=args.robot,
        plan=args.plan,
        seed=args.seed,
        gps_rate=args.gps_rate,
        corrupt=args.corrupt,
        ir_rate=args.ir_rate,
        gyro_rate=args.gyro_rate,
    )
    if args.ir_link is None and args.config is None:
        args.ir_link = "serial"  # a bare `hilnav fake` serves the board on its serial port
    if args.ir_link is not None:
        link = "serial" if args.ir_link == "serial" else "can"
        cfg = dataclasses.replace(
            cfg, devices=dataclasses.replace(
                cfg.devices, ir=dataclasses.replace(cfg.devices.ir, link=link)
            )
        )  # fmt: skip
    knobs = FakeKnobs(
        link_dir=args.link_dir,
        baud=args.baud,
        drop=args.drop,
        vanish_after=args.vanish_after,
        vanish_for=args.vanish_for,
        replay=replay,
        replay_fast=args.replay_fast,
        ir_link="python-can" if args.ir_link == "python-can" else "",
    )
    devices = None
    if args.devices is not None:
        devices = [d.strip() for d in args.devices.split(",") if d.strip()]
    runner = build_fakes(cfg, knobs, devices)
    bus = None
    if args.zenoh_connect:
        from hilnav.bus import Bus, ZenohSettings
        from hilnav.fakeset import TruthPublisher

        # gossip on, listening on loopback only: when the daemon gossips too (the demo),
        # other sessions (the operator) reach this one directly and see the truth
        bus = Bus(
            cfg.name,
            ZenohSettings(
                listen=("tcp/127.0.0.1:0",), connect=(args.zenoh_connect,), gossip_scouting=True
            ),
        )
        rate = args.truth_rate or cfg.simulation.truth_rate_hz
        runner.add(TruthPublisher(cfg.name, bus, rate))
    done = threading.Event()

    def on_signal(signum, frame):
        done.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    runner.start()
    try:
        print(json.dumps(runner.ports()), flush=True)
        if args.config == "-":
            _watch_stdin(done)
        done.wait(args.duration)
    finally:
        runner.stop()
        if bus is not None:
            bus.close()
    sys.stdout.flush()
    return 0
