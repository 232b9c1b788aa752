"""Loader of CARMEN text logs (laser scans, odometry, corrected poses) as a :class:`LaserLog`.

CARMEN logs are text, one message per line, the first word its kind. Read here:

- ``ODOM x y theta tv rv accel timestamp host logger_timestamp``: the robot's odometry;
- ``FLASER n r_1..r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp``:
  a front laser scan over 180 deg from -90 deg (:func:`mapping.laser_log.laser_angles`)
  with the laser's pose and the robot's pose;
- ``ROBOTLASER1 type start fov resolution max_range accuracy remission_mode n r_1..r_n
  m rem_1..rem_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
  forward_safety side_safety turn_axis timestamp host logger_timestamp``;
- ``RAWLASER1`` (as ROBOTLASER1 up to the remissions, then the timestamps; no pose: the
  odometry at the scan's time is used);
- ``TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta timestamp host
  logger_timestamp`` (simulators): reference poses.

Other kinds (PARAM, SYNC, NEFF, RLASER, ...) are counted and ignored; a line that does
not parse is counted (``bad_lines``) and skipped, never raised.

**Corrected poses.** A log written after scan-matching SLAM (GMapping's ``.gfs`` logs)
carries corrected poses in its laser lines, and its ODOM lines are the corrected
odometry: at every keyframe GMapping writes an ODOM line without a timestamp (0) holding
the corrected pose, and the odometry carries on from there. The raw odometry is rebuilt
as the chain of relative motions between consecutive ODOM lines with those jumps left
out (``odometry_resets``). The laser lines' poses are taken as corrected poses (the
reference) when they part from that odometry by more than ``corrected_gap_m`` after
aligning the starts (``poses="auto"``), or when told (``poses="corrected"``); then the
scans' odometry is the rebuilt chain at their times. TRUEPOS lines give the reference
otherwise. Timestamps that go backwards are repaired (:func:`mapping.laser_log.repair_times`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from mapping.laser_log import LaserLog, LaserLogError, laser_angles, reference_error, repair_times
from mapping.se2 import compose, relative
from numerics.angles import wrap

Poses = Literal["auto", "corrected", "odometry"]
LASERS = ("FLASER", "ROBOTLASER1", "RAWLASER1")


@dataclass
class _Scan:
    t: float
    ranges: np.ndarray
    angles: tuple[float, float, int]  # start, step, count
    max_range: float | None
    laser: np.ndarray | None  # laser pose
    robot: np.ndarray | None  # robot pose


@dataclass
class _Parsed:
    counts: Counter = field(default_factory=Counter)
    odom_t: list[float] = field(default_factory=list)  # nan: no valid timestamp (a reset)
    odom: list[tuple[float, float, float]] = field(default_factory=list)
    scans: dict[str, list[_Scan]] = field(default_factory=dict)
    true_t: list[float] = field(default_factory=list)
    true: list[tuple[float, float, float]] = field(default_factory=list)


def _floats(tokens: list[str]) -> list[float]:
    return [float(x) for x in tokens]


def _stamp(tokens: list[str], i: int) -> float:
    """The ipc timestamp at ``tokens[i]`` (logger timestamp as fallback); NaN if <= 0."""
    for j in (i, i + 2):
        if j < len(tokens):
            try:
                v = float(tokens[j])
            except ValueError:
                continue
            if np.isfinite(v) and v > 0:
                return v
    return float("nan")


def _parse_line(p: _Parsed, tok: list[str]) -> None:
    kind = tok[0]
    if kind == "ODOM":
        x, y, th = _floats(tok[1:4])
        if len(tok) < 8:
            raise ValueError("ODOM needs x y theta tv rv accel timestamp")
        p.odom_t.append(_stamp(tok, 7))
        p.odom.append((x, y, th))
    elif kind == "TRUEPOS":
        x, y, th = _floats(tok[1:4])
        t = _stamp(tok, 7)
        if not np.isfinite(t):
            raise ValueError("TRUEPOS without a timestamp")
        p.true_t.append(t)
        p.true.append((x, y, th))
    elif kind == "FLASER":
        n = int(tok[1])
        r = np.array(_floats(tok[2 : 2 + n]))
        rest = _floats(tok[2 + n : 2 + n + 6])
        if len(r) != n or len(rest) != 6:
            raise ValueError("FLASER line too short")
        t = _stamp(tok, 2 + n + 6)
        step = np.pi / (n - 1) if n % 2 else np.pi / n
        scan = _Scan(t, r, (-np.pi / 2, step, n), None, np.array(rest[:3]), np.array(rest[3:]))
        p.scans.setdefault(kind, []).append(scan)
    elif kind in ("ROBOTLASER1", "RAWLASER1"):
        start, _fov, res, max_r = _floats(tok[2:6])
        n = int(tok[8])
        r = np.array(_floats(tok[9 : 9 + n]))
        m = int(tok[9 + n])
        i = 10 + n + m
        if kind == "ROBOTLASER1":
            poses = _floats(tok[i : i + 6])
            if len(poses) != 6:
                raise ValueError("ROBOTLASER1 line too short")
            laser, robot = np.array(poses[:3]), np.array(poses[3:])
            i += 11
        else:
            laser = robot = None
        if len(r) != n or i >= len(tok):
            raise ValueError(f"{kind} line too short")
        scan = _Scan(_stamp(tok, i), r, (start, res, n), max_r, laser, robot)
        p.scans.setdefault(kind, []).append(scan)
    else:
        p.counts["other_lines"] += 1
        return
    p.counts[kind] += 1


def parse_carmen(path: str | Path) -> _Parsed:
    """Every line of a CARMEN log, parsed (bad lines counted in ``counts``)."""
    f = Path(path)
    if not f.is_file():
        raise LaserLogError(f"CARMEN log not found: {f}")
    p = _Parsed()
    with open(f, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            tok = line.split()
            if not tok or tok[0].startswith("#"):
                continue
            try:
                _parse_line(p, tok)
            except (ValueError, IndexError):
                p.counts["bad_lines"] += 1
    return p


def raw_odometry(poses: np.ndarray, stamped: np.ndarray) -> np.ndarray:
    """The odometry chain with the jumps into unstamped lines (resets) left out."""
    out = np.empty_like(poses)
    if len(poses) == 0:
        return out
    out[0] = poses[0]
    for i in range(1, len(poses)):
        if stamped[i]:
            out[i] = compose(out[i - 1], relative(poses[i - 1], poses[i]))
        else:
            out[i] = out[i - 1]
    return out


def _at(t: np.ndarray, tq: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses interpolated at times ``tq`` (held constant outside ``t``)."""
    th = np.unwrap(poses[:, 2])
    return np.column_stack([np.interp(tq, t, poses[:, 0]), np.interp(tq, t, poses[:, 1]),
                            wrap(np.interp(tq, t, th))])  # fmt: skip


def load_carmen(
    path: str | Path,
    poses: Poses = "auto",
    max_range_m: float = 80.0,
    corrected_gap_m: float = 0.25,
) -> LaserLog:
    """Load a CARMEN log (see the module doc). ``max_range_m``: readings at or beyond it
    are "no return" (FLASER lines do not say; ROBOTLASER1 lines do)."""
    if poses not in ("auto", "corrected", "odometry"):
        raise LaserLogError(f"poses must be auto, corrected or odometry, got {poses!r}")
    p = parse_carmen(path)
    counts = Counter(p.counts)
    kinds = [k for k in LASERS if p.scans.get(k)]
    if not kinds:
        raise LaserLogError(
            f"{path}: no laser scans (FLASER, ROBOTLASER1 or RAWLASER1 lines) in the log"
        )
    kind = max(kinds, key=lambda k: len(p.scans[k]))
    scans = p.scans[kind]
    nbeams = Counter(s.angles[2] for s in scans).most_common(1)[0][0]
    counts["scans_other_size"] = sum(s.angles[2] != nbeams for s in scans)
    scans = [s for s in scans if s.angles[2] == nbeams]
    counts["scans_other_laser"] = sum(len(p.scans[k]) for k in kinds if k != kind)

    # One clock for all stamped lines: repair the scans' and odometry's times together.
    ot = np.array(p.odom_t, dtype=float)
    stamped = np.isfinite(ot)
    counts["odometry_resets"] = int((~stamped).sum())
    st = np.array([s.t for s in scans], dtype=float)
    counts["scans_unstamped"] = int((~np.isfinite(st)).sum())
    scans = [s for s, ok in zip(scans, np.isfinite(st), strict=True) if ok]
    st = st[np.isfinite(st)]
    if not scans:
        raise LaserLogError(f"{path}: no laser scan has a timestamp")
    st, rep_s = repair_times(st)
    odo = np.array(p.odom, dtype=float).reshape(-1, 3)
    chain = raw_odometry(odo, stamped)
    ot_ok, chain_ok = ot[stamped], chain[stamped]
    rep_o = 0
    if len(ot_ok):
        ot_ok, rep_o = repair_times(ot_ok)
    counts["timestamps_repaired"] = rep_s + rep_o

    ranges = np.stack([s.ranges for s in scans])
    start, step, n = scans[0].angles
    angles = start + step * np.arange(n) if kind != "FLASER" else laser_angles(n)
    max_r = scans[0].max_range if scans[0].max_range else max_range_m
    robot = np.array([s.robot if s.robot is not None else [np.nan] * 3 for s in scans])
    laser = np.array([s.laser if s.laser is not None else [np.nan] * 3 for s in scans])
    have_robot = bool(np.all(np.isfinite(robot)))
    offset = (0.0, 0.0, 0.0)
    if have_robot and np.all(np.isfinite(laser)):
        rel = relative(robot, laser)
        offset = tuple(float(v) for v in np.median(rel, axis=0))
    odom_at = _at(ot_ok, st, chain_ok) if len(ot_ok) >= 2 else None

    reference = None
    ref_source = ""
    corrected = poses == "corrected"
    if poses == "auto" and have_robot and odom_at is not None:
        corrected = reference_error(robot, odom_at) > corrected_gap_m
    if corrected:
        if not have_robot:
            raise LaserLogError(f"{path}: {kind} lines carry no pose to take as corrected")
        if odom_at is None:
            raise LaserLogError(
                f"{path}: the scans' poses are corrected but the log has no ODOM lines "
                "to give the raw odometry"
            )
        reference, odom = robot, odom_at
        ref_source = f"corrected poses of the {kind} lines"
    else:
        if have_robot:
            odom = robot
        elif odom_at is not None:
            odom = odom_at
        else:
            raise LaserLogError(f"{path}: no odometry (ODOM lines or scan poses)")
        if len(p.true_t) >= 2:
            tt, rep_t = repair_times(np.array(p.true_t))
            counts["timestamps_repaired"] += rep_t
            reference = _at(tt, st, np.array(p.true))
            ref_source = "TRUEPOS lines"
    counts["scans"] = len(scans)
    return LaserLog(st, ranges, angles, float(max_r), odom, reference, offset,
                    Path(path).name, ref_source, dict(counts))  # fmt: skip


def keyframes(path: str | Path) -> tuple[list[np.ndarray], np.ndarray]:
    """The laser scans of a corrected log (range vectors) and their robot poses (K, 3),
    to match against the scans of another file (:func:`mapping.laser_log.match_keyframes`)."""
    p = parse_carmen(path)
    kinds = [k for k in ("FLASER", "ROBOTLASER1") if p.scans.get(k)]
    if not kinds:
        raise LaserLogError(f"{path}: no laser scans with poses (FLASER or ROBOTLASER1)")
    scans = p.scans[max(kinds, key=lambda k: len(p.scans[k]))]
    return [s.ranges for s in scans], np.array([s.robot for s in scans], dtype=float)


def load_laser_log(
    path: str | Path,
    reference: str | Path | None = None,
    poses: Poses = "auto",
    max_range_m: float = 80.0,
) -> LaserLog:
    """A CARMEN log or a scan ``.mat`` file; with ``reference`` (a corrected CARMEN log of
    the same run) the reference poses come from its keyframes
    (:func:`mapping.laser_log.attach_reference`). A corrected log's sparse reference is
    filled in along the odometry the same way (:func:`mapping.laser_log.densify`)."""
    from mapping.laser_log import attach_reference, densify, load_scan_mat

    p = Path(path)
    if p.suffix.lower() == ".mat":
        log = load_scan_mat(p, max_range_m)
    else:
        log = load_carmen(p, poses, max_range_m)
    if reference is not None:
        ranges, key_poses = keyframes(reference)
        log = attach_reference(log, ranges, key_poses, Path(reference).name)
    elif log.reference is not None:
        log.reference = densify(log.odom, log.reference)
    return log
