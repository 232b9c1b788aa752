"""``hilnav map export LOG --out DIR [--at T]``: a logged map as nav2 map files and a PNG."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hilnav.errors import CliError

PICTURE_PX = 512  # the picture's longer side is scaled up to about this many pixels


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("map", help="export a logged occupancy grid (nav2 map files, PNG)")
    msub = p.add_subparsers(dest="map_command", metavar="ACTION")
    ex = msub.add_parser(
        "export",
        help="a robot's map from a log as nav2 map_server files (image + YAML) and a PNG",
        description="Write the last map of LOG (or the last one at or before --at T seconds "
        "after the log's first record) as nav2 map_server files: <robot>_map.yaml with "
        "<robot>_map.pgm (trinary or raw mode) or <robot>_map.png (scale mode: RGBA, "
        "never-observed cells transparent, as nav2 needs), and a picture <robot>_map.png "
        "(white free, black occupied, grey unknown). Prints a JSON report on its last line.",
    )
    ex.add_argument("log", help="MCAP log")
    ex.add_argument("--out", required=True, help="output folder (created if missing)")
    ex.add_argument("--at", type=float, metavar="T", help="seconds after the log's start")
    ex.add_argument("--robot", help="whose map (needed when the log holds several robots')")
    ex.add_argument(
        "--mode",
        default="trinary",
        choices=("trinary", "scale", "raw"),
        help="nav2 map mode (default trinary: occupied / free / unknown)",
    )
    ex.add_argument("--occupied-thresh", type=float, default=0.65, help="default 0.65")
    ex.add_argument("--free-thresh", type=float, default=0.196, help="default 0.196")
    ex.set_defaults(func=run_export)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_export(args: argparse.Namespace) -> int:
    import numpy as np

    from hilnav.analysis.maps import logged_map
    from mapping.export import write_png
    from mapping.mapfile import read_map, write_map

    log = Path(args.log)
    if not log.is_file():
        raise CliError(f"no such log file: {args.log}")
    try:
        found = logged_map(log, robot=args.robot, at_s=args.at)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        base = out / f"{found.robot}_map"
        image, yml = write_map(found.msg, base, args.mode, args.occupied_thresh, args.free_thresh)
        files = [image, yml]
        if args.mode != "scale":  # a scale map's RGBA PNG is its own picture
            rows = len(found.msg.data) // max(found.msg.column_count, 1)
            scale = max(1, min(8, PICTURE_PX // max(rows, found.msg.column_count, 1)))
            files.append(write_png(found.msg, base.with_suffix(".png"), scale=scale))
        loaded = read_map(yml)  # as nav2's map_server will load it
    except ValueError as exc:
        raise CliError(str(exc)) from None
    cells = loaded.cells
    report = {
        "robot": found.robot,
        "at_s": round(found.at_s, 3),
        "log_time_ns": found.log_time_ns,
        "mode": args.mode,
        "rows": int(cells.shape[0]),
        "cols": int(cells.shape[1]),
        "resolution_m": loaded.resolution,
        "origin": list(loaded.origin),
        "occupied_cells": int(np.count_nonzero(cells == 100)),
        "free_cells": int(np.count_nonzero(cells == 0)),
        "unknown_cells": int(np.count_nonzero(cells == -1)),
        "files": [str(f) for f in files],
    }
    print(f"map of {found.robot} at {found.at_s:.1f} s -> {yml} ({args.mode})")
    print(json.dumps(report, sort_keys=True))
    return 0
