"""``hilnav import victoria-park DIR OUT.mcap``: public data sets as hilnav logs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("import", help="turn a public data set into a hilnav MCAP log")
    isub = p.add_subparsers(dest="import_command", metavar="DATASET")
    vp = isub.add_parser(
        "victoria-park",
        help="Victoria Park (ACFR): controls, tree detections, GPS",
        description="Write the Victoria Park data set (the folder with aa3_dr.mat, "
        "aa3_gpsx.mat and VictoriaParkSinSincronizar.mat) as an MCAP log for replay and "
        "analyze: /<robot>/control, /<robot>/landmark_scan, /<robot>/gps.",
    )
    vp.add_argument("dir", help="folder of the data set's .mat files")
    vp.add_argument("out", help="MCAP log to write")
    vp.add_argument("--robot", default="vp", help="robot name in the topics (default vp)")
    vp.add_argument("--duration", type=float, help="only the first S seconds")
    vp.add_argument(
        "--compression",
        default="zstd",
        choices=("zstd", "lz4", "none"),
        help="MCAP chunk compression (zstd: small files; lz4: faster; none)",
    )
    vp.set_defaults(func=run_victoria_park)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_victoria_park(args: argparse.Namespace) -> int:
    from hilnav.importers.victoria_park import import_victoria_park

    if args.duration is not None and args.duration <= 0:
        raise CliError("--duration must be > 0 seconds")
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise CliError(f"output folder does not exist: {out.parent}")
    try:
        rep = import_victoria_park(
            args.dir, out, robot=args.robot, duration_s=args.duration, compression=args.compression
        )
    except ImportError as exc:
        raise CliError(f"the Victoria Park loader is not available: {exc}") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None
    d = rep.as_dict()
    print(f"imported {sum(rep.counts.values())} messages ({d['duration_s']} s) into {out}")
    print(json.dumps(d, sort_keys=True))
    return 0
