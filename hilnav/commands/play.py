"""``hilnav play LOG [--rate R] [--loop] [--topics ...]``: a log back on the Zenoh bus in
real time, stamps shifted to now (:mod:`hilnav.play`), until its end or SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
import json
import signal
import threading
from pathlib import Path

from hilnav.commands.zenoh_args import add_zenoh_args, open_bus, zenoh_settings
from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "play",
        help="publish a log's messages on Zenoh in real time, as if live (like ros2 bag play)",
        description="Put the messages of LOG on hilnav/<robot>/<topic> at the pace of their "
        "log times (times --rate), sent in the name of the robot each topic belongs to, "
        "with every stamp shifted to now. Views and raw bytes are left out unless --topics "
        "names them. Ends at the end of the log (unless --loop) or on SIGINT/SIGTERM; "
        "prints a JSON report on its last line.",
    )
    p.add_argument("log", help="MCAP log (a truncated one too)")
    p.add_argument("--rate", type=float, default=1.0, help="speed factor (default 1: real time)")
    p.add_argument("--loop", action="store_true", help="start again at the end, until stopped")
    p.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help="only these MCAP topics (exact, or patterns such as '/r1/*'); may name views "
        "and raw bytes",
    )
    add_zenoh_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hilnav.play import Player

    log = Path(args.log)
    if not log.is_file():
        raise CliError(f"no such log file: {log}")
    if not args.rate > 0:
        raise CliError(f"--rate {args.rate}: must be > 0")
    settings = zenoh_settings(args)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.set())
    bus = open_bus("player", settings)
    try:
        player = Player(log, bus, rate=args.rate, topics=args.topics, stop=stop)
        rep = player.play(loop=args.loop)
    except ValueError as exc:  # not an MCAP file
        raise CliError(str(exc)) from None
    finally:
        bus.close()
    print(
        f"hilnav play: {rep.published} messages on {len(rep.per_topic)} topics in "
        f"{rep.passes} pass(es){', stopped' if rep.stopped else ''}",
        flush=True,
    )
    print(json.dumps(rep.as_dict(), sort_keys=True), flush=True)
    return 0
