"""``hilnav analyze LOG [--out DIR]``: errors, drift, map quality, CP boxes; PNGs + JSON."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "analyze",
        help="analyse a log: path error, heading drift and NEES, map scores, CP boxes; PNGs + JSON",
        description="Compute what the log allows (path error against the truth or GPS, "
        "heading drift per metre and the heading filter's NEES, the map's scores against the "
        "floor plan named in the log or the log's reference map, the association's checks, CP "
        "box containment and areas, diagnostics), write PNG plots and summary.json to DIR, "
        "and print a digest (with --json: the JSON summary).",
    )
    p.add_argument("log", help="MCAP log (a truncated one is read up to its last record)")
    p.add_argument("--out", help="output directory (default: <log without .mcap>-analysis)")
    p.add_argument("--plan", help="floor plan for the map match ratio (default: from the log)")
    p.add_argument("--no-plots", action="store_true", help="only the JSON summary")
    p.add_argument(
        "--json", action="store_true", help="print the JSON summary instead of the digest"
    )
    p.set_defaults(func=run)


def default_out(log: Path) -> Path:
    return log.with_name(log.stem + "-analysis")


def run(args: argparse.Namespace) -> int:
    from hilnav.analysis.analyze import analyze
    from hilnav.analysis.report import digest, write_report

    log = Path(args.log)
    if not log.is_file():
        raise CliError(f"no such log file: {log}")
    out = Path(args.out) if args.out else default_out(log)
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out}: a file of that name exists; name a directory")
    try:
        result = analyze(log, plan=args.plan)
    except ValueError as exc:
        msg = str(exc)
        raise CliError(msg if msg.startswith(str(log)) else f"{log}: {msg}") from None
    summary = write_report(result, out, plots=not args.no_plots)
    if args.json:
        print(json.dumps(summary, sort_keys=True))
        return 0
    for line in digest(result):
        print(line)
    print(f"summary and plots: {out}/ (the JSON: hilnav analyze {log} --json)")
    return 0
