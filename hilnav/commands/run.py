"""``hilnav run [--config FILE] [--foxglove [PORT]]``: the robot daemon until SIGINT/SIGTERM
(or --seconds), optionally serving its topics live to Foxglove (:mod:`hilnav.live`)."""

from __future__ import annotations

import argparse
import signal
import sys
from typing import Any

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run the robot daemon (devices, services, Zenoh, MCAP log)",
        description="Run the daemon of one robot: one device loop reading every device, the services, "
        "publishing on Zenoh under hilnav/<robot>/<topic>, logging every message to one MCAP "
        "file. Without --config: the embedded defaults, a simulated Pioneer with all sensors "
        "(the emulated devices are started as a subprocess). SIGINT/SIGTERM stop the motors, "
        "close the log and exit 0.",
    )
    p.add_argument("--config", help="robot TOML file (see: hilnav config example)")
    p.add_argument("--log", help="MCAP file to write (default: [log] dir/<robot>-<UTC>.mcap)")
    p.add_argument("--seconds", type=float, default=None, help="stop after S seconds")
    p.add_argument("--quiet", action="store_true", help="do not print the config summary")
    p.add_argument(
        "--foxglove",
        nargs="?",
        type=int,
        const=8765,
        metavar="PORT",
        help="serve the robot's topics live on the Foxglove WebSocket protocol, the same "
        "channels as the log (default port 8765; 0 = any free port)",
    )
    p.add_argument(
        "--foxglove-host",
        default="127.0.0.1",
        metavar="HOST",
        help="address the live view listens on (default 127.0.0.1: this machine only)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hilnav.config import ConfigError, load_config, summary
    from hilnav.daemon import Daemon, DaemonError

    try:
        cfg = load_config(args.config)
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    sinks = (
        {"live": live_bridge(args.foxglove, args.foxglove_host)}
        if args.foxglove is not None
        else {}
    )
    daemon = Daemon(cfg, log_path=args.log, sinks=sinks)

    def on_signal(signum, frame):
        daemon.request_stop()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        daemon.start()
    except DaemonError as exc:
        raise CliError(str(exc)) from None
    if not args.quiet:
        print(summary(daemon.cfg), file=sys.stderr)
    print(f"hilnav run: {cfg.name} up; log {daemon.log_path}", flush=True)
    if sinks:
        print(f"hilnav run: live view on {sinks['live'].url} (Foxglove WebSocket)", flush=True)
    try:
        daemon.wait(args.seconds)
    finally:
        daemon.stop()
    s = daemon.stats
    print(
        f"hilnav run: stopped; {s.processed} messages, {s.logged} logged, {s.dropped} dropped; "
        f"log {daemon.log_path}",
        flush=True,
    )
    mapping = daemon.runtime.pipeline.mapping
    if mapping is not None:
        print(f"hilnav run: mapping: {mapping.summary()}", flush=True)
    return 0


def live_bridge(port: int, host: str) -> Any:
    """A :class:`hilnav.live.LiveBridge` on ``host:port``, or a CliError saying why not."""
    from hilnav.live import LiveBridge, LiveError

    if not 0 <= port <= 65535:
        raise CliError(f"--foxglove {port}: a port is 0..65535 (0: any free port)")
    try:
        return LiveBridge(port, host)
    except LiveError as exc:
        raise CliError(str(exc)) from None
