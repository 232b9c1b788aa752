"""``hilnav log info FILE`` and ``hilnav log recover IN OUT``: inspect and repair MCAP logs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("log", help="inspect (info) and repair (recover) MCAP logs")
    lsub = p.add_subparsers(dest="log_command", metavar="ACTION")
    info = lsub.add_parser(
        "info", help="topics, schemas, counts, rates and duration of a log (also truncated)"
    )
    info.add_argument("file", help="MCAP log")
    info.add_argument("--json", action="store_true", help="print one JSON object instead")
    info.set_defaults(func=run_info)
    rec = lsub.add_parser(
        "recover",
        help="rewrite a truncated log (killed writer) into a valid one",
        description="Copy every complete record of IN into a valid MCAP OUT and report what "
        "was lost (the torn tail). Prints a JSON report on its last line.",
    )
    rec.add_argument("input", metavar="IN", help="truncated MCAP log")
    rec.add_argument("output", metavar="OUT", help="new MCAP log to write")
    rec.add_argument(
        "--compression",
        default="zstd",
        choices=("zstd", "lz4", "none"),
        help="MCAP chunk compression (zstd: small files; lz4: faster; none)",
    )
    rec.set_defaults(func=run_recover)
    can_ = lsub.add_parser(
        "export-can",
        help="the IR board's raw CAN frames as a python-can log (.asc, .blf, .csv, .trc ...)",
        description="Write every raw CAN frame of the log (the IR board on CAN) to OUT in the "
        "format its extension names, with python-can's own writer; can.player and "
        "can.LogReader read it back.",
    )
    can_.add_argument("file", metavar="LOG", help="MCAP log")
    can_.add_argument("out", metavar="OUT", help="e.g. frames.asc or frames.blf")
    can_.set_defaults(func=run_export_can)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _existing(path: str) -> Path:
    p = Path(path)
    if not p.is_file():
        raise CliError(f"no such log file: {path}")
    return p


def run_info(args: argparse.Namespace) -> int:
    from hilnav.log.info import log_info

    try:
        info = log_info(_existing(args.file))
    except ValueError as exc:
        raise CliError(str(exc)) from None
    print(json.dumps(info.as_dict(), sort_keys=True) if args.json else info.table())
    return 0


def run_recover(args: argparse.Namespace) -> int:
    from hilnav.log.recover import recover

    src = _existing(args.input)
    try:
        rep = recover(src, args.output, compression=args.compression)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    d = rep.as_dict()
    state = "was complete" if rep.input_complete else "was truncated"
    print(
        f"recovered {rep.messages} messages on {rep.channels} channels "
        f"({d['duration_s']:.3f} s) into {rep.output}; input {state}, "
        f"{rep.lost_bytes} tail bytes dropped, {rep.bad_chunks} bad chunks"
    )
    print(json.dumps(d, sort_keys=True))
    return 0


def run_export_can(args: argparse.Namespace) -> int:
    from hilnav.log.can_export import export_can
    from hilnav.log.reader import read_metadata
    from hilnav.replay.resolve import resolve_config

    src = _existing(args.file)
    try:
        meta = read_metadata(src).get("hilnav", {})
        config, where = resolve_config(None, meta)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if config.devices.ir.link != "can":
        raise CliError(f"{src}: its IR board is on a serial link ({where}): no CAN frames")
    try:
        n = export_can(src, args.out)
    except ValueError as exc:  # python-can: an extension it has no writer for
        raise CliError(f"{args.out}: {exc}") from None
    print(f"{n} CAN frames written to {args.out}")
    return 0
