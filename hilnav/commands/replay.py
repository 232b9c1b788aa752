"""``hilnav replay LOG [--config FILE] [--out NEW.mcap] [--from-raw]``: run the services again."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hilnav.commands import add_compression
from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="feed a log's device messages through the services again (deterministic)",
        description="Feed the recorded device messages (odometry, gyro, gps, ir; a data "
        "set's controls, scans, velocities, range-bearing) of LOG, or "
        "with --from-raw the raw device bytes decoded again by the drivers' codecs, through "
        "the services (hilnav.pipeline) as fast as possible, and write a new log with the "
        "new outputs. Same input and parameters give the same output bytes. Prints a JSON "
        "report on its last line.",
    )
    p.add_argument("log", help="input MCAP log")
    p.add_argument(
        "--config", help="robot TOML (default: the one recorded in the log, else defaults)"
    )
    p.add_argument("--out", help="output log (default: <log without .mcap>-replay.mcap)")
    p.add_argument("--from-raw", action="store_true", help="decode the raw bytes again")
    p.add_argument(
        "--pipeline",
        default="auto",
        choices=("auto", "daemon", "landmark-slam", "velocity"),
        help="services to run: the daemon's (Pioneer sensors), EKF-SLAM over controls and "
        "landmark scans (Victoria Park), or every robot's velocity-odometry services at once "
        "(MRCLAM); auto picks by the log's content",
    )
    add_compression(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hilnav.replay.replayer import replay

    log = Path(args.log)
    if not log.is_file():
        raise CliError(f"no such log file: {log}")
    out = Path(args.out) if args.out else log.with_name(log.stem + "-replay.mcap")
    try:
        rep = replay(
            log,
            out,
            config_path=args.config,
            from_raw=args.from_raw,
            progress=not args.no_progress and sys.stderr.isatty(),
            compression=args.compression,
            pipeline=args.pipeline,
        )
    except ValueError as exc:  # ConfigError is a ValueError: its message names the fix
        raise CliError(str(exc)) from None
    d = rep.as_dict()
    fed = sum(rep.fed.values())
    made = sum(rep.outputs.values())
    print(f"replayed {fed} device messages of {rep.robot} -> {made} outputs into {out}")
    if rep.pipeline_errors:
        print(f"warning: {rep.pipeline_errors} messages made the services fail", file=sys.stderr)
    print(json.dumps(d, sort_keys=True))
    return 0
