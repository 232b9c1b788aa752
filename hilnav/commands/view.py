"""``hilnav view [--connect ENDPOINT ...] [--port PORT]``: every robot on the Zenoh bus,
live in Foxglove (:mod:`hilnav.live`), until SIGINT/SIGTERM (or --seconds)."""

from __future__ import annotations

import argparse
import signal
import threading

from hilnav.commands.zenoh_args import add_zenoh_args, open_bus, zenoh_settings
from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view",
        help="serve every robot on the bus live to Foxglove (WebSocket)",
        description="Join the Zenoh bus, subscribe to hilnav/*/** (every robot, and logs "
        "played by `hilnav play`) and serve the messages on the Foxglove WebSocket "
        "protocol with the channels and schemas of the MCAP log: /<robot>/<topic> as "
        "hilnav JSON and the Foxglove views. Open ws://HOST:PORT in the Foxglove app. "
        "SIGINT/SIGTERM stop it.",
    )
    add_zenoh_args(p)
    p.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765; 0: any)")
    p.add_argument(
        "--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine)"
    )
    p.add_argument("--seconds", type=float, default=None, help="stop after S seconds")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hilnav.commands.run import live_bridge
    from hilnav.live import serve_bus

    settings = zenoh_settings(args)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.set())
    bridge = live_bridge(args.port, args.host)
    try:
        bus = open_bus("viewer", settings)
    except CliError:
        bridge.close()
        raise
    try:
        serve_bus(bus, bridge)
        where = ", ".join([*settings.connect, *settings.listen])
        print(f"hilnav view: {bridge.url} (Foxglove WebSocket); Zenoh {where}", flush=True)
        stop.wait(args.seconds)
    finally:
        bus.close()
        bridge.close()
    print(f"hilnav view: stopped; {bus.stats.received} messages received", flush=True)
    return 0
