"""``hilnav import victoria-park|mrclam DIR OUT.mcap``, ``hilnav import carmen FILE
OUT.mcap``: public data sets as hilnav logs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hilnav.commands import add_compression
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
    add_compression(vp)
    vp.set_defaults(func=run_victoria_park)
    mr = isub.add_parser(
        "mrclam",
        help="UTIAS MRCLAM: five robots' velocity odometry, range-bearing, landmarks, truth",
        description="Write an MRCLAM run directory (Barcodes.dat, Landmark_Groundtruth.dat, "
        "RobotN_Odometry/Measurement/Groundtruth.dat) as a multi-robot MCAP log for replay "
        "and analyze: per robot r<N>, /r<N>/velocity, /r<N>/landmark_range_bearing, "
        "/r<N>/peer_range_bearing, /r<N>/landmark_map (once) and /r<N>/truth (gaps "
        "flagged). Log time = the data set's clock. Prints a JSON report on its last line.",
    )
    mr.add_argument("dir", help="MRCLAM run directory (e.g. MRCLAM_Dataset6)")
    mr.add_argument("out", help="MCAP log to write")
    mr.add_argument("--seconds", type=float, help="only S seconds (from the start)")
    mr.add_argument("--start", type=float, default=0.0, help="skip the first S seconds of the run")
    mr.add_argument("--robots", help="robot numbers to import, e.g. 1,2 (default: all)")
    add_compression(mr)
    mr.set_defaults(func=run_mrclam)
    _register_carmen(isub)
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


def _robot_numbers(text: str | None) -> list[int] | None:
    if text is None:
        return None
    try:
        nums = sorted({int(p) for p in text.split(",") if p.strip()})
    except ValueError:
        raise CliError(f"--robots {text!r}: give robot numbers, e.g. 1,2") from None
    if not nums or min(nums) < 1:
        raise CliError(f"--robots {text!r}: give robot numbers >= 1, e.g. 1,2")
    return nums


def run_mrclam(args: argparse.Namespace) -> int:
    from hilnav.importers.mrclam import import_mrclam

    if args.seconds is not None and args.seconds <= 0:
        raise CliError("--seconds must be > 0")
    if args.start < 0:
        raise CliError("--start must be >= 0 seconds")
    robots = _robot_numbers(args.robots)
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise CliError(f"output folder does not exist: {out.parent}")
    try:
        rep = import_mrclam(
            args.dir,
            out,
            seconds=args.seconds,
            start_s=args.start,
            robots=robots,
            compression=args.compression,
        )
    except ValueError as exc:  # MrclamError names the file and the problem
        raise CliError(str(exc)) from None
    d = rep.as_dict()
    total = sum(d["messages"].values())
    print(f"imported {total} messages of {', '.join(rep.robots)} ({d['duration_s']} s) into {out}")
    print(json.dumps(d, sort_keys=True))
    return 0


def _register_carmen(isub: argparse._SubParsersAction) -> None:
    c = isub.add_parser(
        "carmen",
        help="a laser log (CARMEN text or scan .mat) with IR sensors emulated at the mounts",
        description="Write a real robot's laser log as an MCAP log for replay and analyze: "
        "/<robot>/odometry, /<robot>/ir (the laser's beams at the IR mounts, Sharp limits "
        "1-5.5 m), /<robot>/truth and /<robot>/reference_map (corrected poses, when the log "
        "or --reference has them), /<robot>/gyro (with --gyro-seed). FILE: a CARMEN log "
        "(ODOM, FLASER, ROBOTLASER1, RAWLASER1, TRUEPOS lines) or a .mat of scans "
        "(beam_data, odom, timestamp).",
    )
    c.add_argument("file", help="CARMEN log or scan .mat file")
    c.add_argument("out", help="MCAP log to write")
    c.add_argument("--robot", default="intel", help="robot name in the topics (default intel)")
    c.add_argument("--reference", help="a corrected CARMEN log of the same run (its keyframes "
                   "give the reference poses, matched by their range vectors)")  # fmt: skip
    c.add_argument(
        "--ir-mounts",
        help='IR mounts "x,y,yaw_deg;x,y,yaw_deg;..." in the robot frame (default: the '
        "config's geometry.ir_mounts)",
    )
    c.add_argument("--ir-noise-seed", type=int, help="Sharp noise model (fakes), seeded")
    c.add_argument("--gyro-seed", type=int, help="emulate a gyro on the reference heading")
    c.add_argument("--scans", type=int, help="only the first N scans")
    c.add_argument(
        "--poses",
        default="auto",
        choices=("auto", "corrected", "odometry"),
        help="what the laser lines' poses are (auto: corrected when they part from ODOM)",
    )
    add_compression(c)
    c.set_defaults(func=run_carmen)


def parse_mounts(text: str) -> list[tuple[float, float, float]]:
    """``"x,y,yaw_deg;..."`` -> [(x, y, yaw_rad), ...]; CliError names a bad entry."""
    import math

    out = []
    for part in text.replace(" ", "").split(";"):
        if not part:
            continue
        try:
            x, y, yaw = (float(v) for v in part.split(","))
        except ValueError:
            raise CliError(f"--ir-mounts: {part!r} is not x,y,yaw_deg") from None
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise CliError(f"--ir-mounts: {part!r} is not finite")
        out.append((x, y, math.radians(yaw)))
    if not 1 <= len(out) <= 8:
        raise CliError(f"--ir-mounts: give 1 to 8 mounts, got {len(out)}")
    return out


def run_carmen(args: argparse.Namespace) -> int:
    import numpy as np

    from hilnav.importers.carmen import import_carmen

    if args.scans is not None and args.scans < 2:
        raise CliError("--scans must be >= 2")
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise CliError(f"output folder does not exist: {out.parent}")
    mounts = np.array(parse_mounts(args.ir_mounts)) if args.ir_mounts else None
    try:
        rep = import_carmen(
            args.file, out, robot=args.robot, reference=args.reference, mounts=mounts,
            ir_noise_seed=args.ir_noise_seed, gyro_seed=args.gyro_seed, scans=args.scans,
            poses=args.poses, compression=args.compression,
        )  # fmt: skip
    except ValueError as exc:
        raise CliError(str(exc)) from None
    d = rep.as_dict()
    print(f"imported {sum(rep.counts.values())} messages ({d['duration_s']} s) into {out}")
    print(json.dumps(d, sort_keys=True))
    return 0
