"""``hilnav fake``: start the emulated devices of one robot and print their ports as JSON."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading

from hilnav.errors import CliError
from hilnav.fakeset import FakeOptions, build_fakes


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fake",
        help="emulated devices on ptys, driven by a simulated world",
        description="Start the emulated devices of one simulated robot. Prints ONE JSON line "
        'mapping device names to port paths (e.g. {"arcos": "/tmp/hilnav-fake-x/arcos"}) once '
        "they are ready, then runs until SIGINT/SIGTERM or --duration.",
    )
    p.add_argument("--config", help="robot TOML file (devices, geometry, noise)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random process")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    p.add_argument("--plan", default="office", help="floor plan: paper_room, office, open_field")
    p.add_argument("--robot", default="r1", help="robot name in the world")
    p.add_argument("--link-dir", help="directory for the stable port links (default: a temp dir)")
    p.add_argument("--baud", type=int, default=None, help="pace the Pioneer's output at this baud")
    p.add_argument("--corrupt", type=float, default=0.0, help="fraction of Pioneer bytes corrupted")
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
        default="serial",
        choices=("serial", "slcan", "python-can"),
        help="IR board on its serial port, or on CAN behind an emulated slcan adapter",
    )
    p.add_argument("--ir-rate", type=int, default=20, help="IR board samples per second")
    p.add_argument("--gyro-rate", type=int, default=100, help="gyro packets per second")
    p.add_argument("--gps-rate", type=float, default=1.0, help="GPS epochs per second (1-10)")
    p.add_argument(
        "--devices",
        default="arcos,ir,gyro,gps",
        help="comma-separated devices to emulate (default arcos,ir,gyro,gps)",
    )
    p.add_argument(
        "--zenoh-connect",
        default=None,
        metavar="ENDPOINT",
        help="publish the ground truth on hilnav/<robot>/truth through a Zenoh peer "
        "connected to ENDPOINT (e.g. tcp/127.0.0.1:7447; multicast scouting off)",
    )
    p.add_argument("--truth-rate", type=float, default=10.0, help="ground-truth messages per s")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    replay = {}
    for item in args.replay:
        dev, sep, path = item.partition("=")
        if not sep or not path:
            raise CliError(f"--replay {item!r}: expected DEVICE=FILE, e.g. gps=recorded.nmea")
        replay[dev] = path
    opts = FakeOptions(
        seed=args.seed,
        plan=args.plan,
        robot=args.robot,
        link_dir=args.link_dir,
        baud=args.baud,
        corrupt=args.corrupt,
        drop=args.drop,
        vanish_after=args.vanish_after,
        vanish_for=args.vanish_for,
        replay=replay,
        config=args.config,
        devices=tuple(d.strip() for d in args.devices.split(",") if d.strip()),
        ir_link=args.ir_link,
        ir_rate_hz=args.ir_rate,
        gyro_rate_hz=args.gyro_rate,
        gps_rate_hz=args.gps_rate,
        replay_fast=args.replay_fast,
    )
    runner = build_fakes(opts)
    bus = None
    if args.zenoh_connect:
        from hilnav.bus import Bus, ZenohSettings
        from hilnav.fakeset import TruthPublisher

        # gossip on, listening on loopback only: when the daemon gossips too (the demo),
        # other sessions (the operator) reach this one directly and see the truth
        bus = Bus(
            opts.robot,
            ZenohSettings(
                listen=("tcp/127.0.0.1:0",), connect=(args.zenoh_connect,), gossip_scouting=True
            ),
        )
        runner.add(TruthPublisher(opts.robot, bus, args.truth_rate))
    done = threading.Event()

    def on_signal(signum, frame):  # noqa: ANN001
        done.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    runner.start()
    try:
        print(json.dumps(runner.ports()), flush=True)
        done.wait(args.duration)
    finally:
        runner.stop()
        if bus is not None:
            bus.close()
    sys.stdout.flush()
    return 0
