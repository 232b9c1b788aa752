"""``hilnav log info FILE``, ``hilnav log cat FILE`` and ``hilnav log recover IN OUT``:
inspect, print and repair MCAP logs."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from hilnav.commands import add_compression
from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "log",
        help="inspect (info, cat), repair (recover) and export CAN frames from (export-can) MCAP logs",
    )
    lsub = p.add_subparsers(dest="log_command", metavar="ACTION")
    info = lsub.add_parser(
        "info", help="topics, schemas, counts, rates and duration of a log (also truncated)"
    )
    info.add_argument("file", help="MCAP log")
    info.add_argument("--json", action="store_true", help="print one JSON object instead")
    info.add_argument(
        "--scan",
        action="store_true",
        help="read every record even when the file has a summary (adds payload bytes)",
    )
    info.set_defaults(func=run_info)
    cat = lsub.add_parser(
        "cat",
        help="print a log's messages, one line each (like mcap cat)",
        description="One line per message: log time (ns), topic, [schema] and the JSON "
        "payload; with --json one JSON object per line. Views and raw bytes included; "
        "a truncated file is read up to its last complete record.",
    )
    cat.add_argument("file", help="MCAP log")
    cat.add_argument(
        "--topics", nargs="+", metavar="TOPIC", help="only these topics (exact or '/r1/*')"
    )
    cat.add_argument("--json", action="store_true", help="one JSON object per line")
    cat.set_defaults(func=run_cat)
    rec = lsub.add_parser(
        "recover",
        help="rewrite a truncated log (killed writer) into a valid one",
        description="Copy every complete record of IN into a valid MCAP OUT and report what "
        "was lost (the torn tail). Prints a JSON report on its last line.",
    )
    rec.add_argument("input", metavar="IN", help="truncated MCAP log")
    rec.add_argument("output", metavar="OUT", help="new MCAP log to write")
    add_compression(rec)
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
        info = log_info(_existing(args.file), scan=args.scan)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    print(json.dumps(info.as_dict(), sort_keys=True) if args.json else info.table())
    return 0


def run_cat(args: argparse.Namespace) -> int:
    from hilnav.log.cat import cat_lines

    path = _existing(args.file)
    try:
        for text in cat_lines(path, args.topics, args.json):
            print(text)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    except BrokenPipeError:  # `hilnav log cat run.mcap | head`: the reader has enough
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
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
