"""A real robot's laser log as arrays: scans, odometry, reference poses (loaders' output).

The IR mapping is judged on real data by taking a laser log (a robot with a scanning
laser, its odometry and, after scan-matching SLAM, corrected poses) and emulating the IR
sensors from the laser's beams. This module holds what every loader returns
(:class:`LaserLog`) and the steps shared by the loaders:

- :func:`repair_times`: logged timestamps that go backwards (the Intel log has a few
  percent of them: one stamp seconds late between two good ones) are found as the
  complement of the longest non-decreasing run of stamps and re-stamped by linear
  interpolation between their good neighbours; then a stamp bunched with a neighbour
  (an interval under a tenth of the median next to one over 0.4 of it: two
  messages logged together, though the robot moved between them) is moved to the middle
  of its neighbours, so motion never seems to happen in no time (counted, never raised);
- :func:`load_scan_mat`: the ``.mat`` piece of the Intel data set (``beam_data``,
  ``odom``, ``timestamp``, ``beam_start``/``beam_end``/``beam_n``);
- :func:`match_keyframes`: which scans a corrected log's keyframes are (identical range
  vectors, in order);
- :func:`densify`: reference poses at every scan from corrected poses at some of them:
  the correction transform C = pose (-) odometry, known at the keyframes, is interpolated
  along the distance driven (linearly in x, y and the unwrapped angle) and composed with
  the odometry, C (+) odometry, so the reference follows the odometry's shape between
  keyframes and meets every keyframe exactly.

Reading files is the only I/O here (scipy.io.loadmat); no clocks, no globals.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mapping.se2 import compose, relative
from numerics.angles import wrap


class LaserLogError(ValueError):
    """A laser log file is missing, unreadable or not of the expected layout."""


@dataclass
class LaserLog:
    """Scans of one laser with the robot's odometry and, when known, reference poses.

    t_s (N,) scan times (s, non-decreasing); ranges (N, B) m, a reading >= max_range_m or
    <= 0 is "no return"; angles (B,) bearings in the laser frame (rad, counter-clockwise,
    0 ahead); laser_on_robot (x, y, yaw) of the laser on the robot; odom (N, 3) the
    robot's raw odometry pose at each scan; reference (N, 3) corrected robot poses (NaN
    rows where none is known; None when the log has none). ``counts``: lines or records
    read, skipped and repaired, by kind.
    """

    t_s: np.ndarray
    ranges: np.ndarray
    angles: np.ndarray
    max_range_m: float
    odom: np.ndarray
    reference: np.ndarray | None = None
    laser_on_robot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str = ""
    reference_source: str = ""
    counts: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def head(self, n: int | None) -> LaserLog:
        """The first ``n`` scans (all with None)."""
        if n is None or n >= len(self):
            return self
        ref = None if self.reference is None else self.reference[:n]
        return LaserLog(self.t_s[:n], self.ranges[:n], self.angles, self.max_range_m,
                        self.odom[:n], ref, self.laser_on_robot, self.source,
                        self.reference_source, dict(self.counts))  # fmt: skip

    def path_length_m(self) -> float:
        """Distance driven by the odometry over the scans."""
        return float(np.hypot(*np.diff(self.odom[:, :2], axis=0).T).sum()) if len(self) > 1 else 0.0


def laser_angles(n: int, start_rad: float = -np.pi / 2, fov_rad: float = np.pi) -> np.ndarray:
    """Bearings of ``n`` beams from ``start_rad``: an odd count spans the whole field of view
    (181 beams: -90..+90 deg), an even one stops one step short (180: -90..+89 deg)."""
    if n < 2:
        raise LaserLogError(f"a laser scan needs at least 2 readings, got {n}")
    step = fov_rad / (n - 1) if n % 2 else fov_rad / n
    return start_rad + step * np.arange(n)


def repair_times(t: np.ndarray) -> tuple[np.ndarray, int]:
    """Timestamps made non-decreasing: the stamps outside the longest non-decreasing
    subsequence are re-stamped by interpolation (by index) between their kept neighbours.
    Returns (times, how many were re-stamped). Non-finite stamps are re-stamped too."""
    t = np.asarray(t, dtype=float)
    n = len(t)
    ok = np.isfinite(t)
    idx = np.flatnonzero(ok)
    keep = np.zeros(n, dtype=bool)
    if len(idx):
        keep[_longest_non_decreasing(t[idx], idx)] = True
    if not keep.any():
        raise LaserLogError("no usable timestamp in the log")
    good = np.flatnonzero(keep)
    out = t.copy()
    bad = np.flatnonzero(~keep)
    out[bad] = np.interp(bad, good, t[good])
    return out, int(len(bad)) + _spread_bunched(out)


def _spread_bunched(t: np.ndarray) -> int:
    """Move bunched stamps (module doc) to the middle of their neighbours, in place."""
    dt = np.diff(t)
    pos = dt[dt > 0]
    if len(pos) < 3:
        return 0
    med = float(np.median(pos))
    moved = np.zeros(len(t), dtype=bool)
    for _ in range(3):  # a run of several bunched stamps spreads out over a few passes
        for i in range(1, len(t) - 1):
            a, b = t[i] - t[i - 1], t[i + 1] - t[i]
            if min(a, b) < 0.1 * med and max(a, b) > 0.4 * med:
                t[i] = 0.5 * (t[i - 1] + t[i + 1])
                moved[i] = True
    return int(moved.sum())


def _longest_non_decreasing(v: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Indices (from ``idx``) of a longest non-decreasing subsequence of ``v`` (patience
    sorting, O(n log n))."""
    tails: list[float] = []
    tail_at: list[int] = []
    prev = np.full(len(v), -1, dtype=np.int64)
    for i, x in enumerate(v):
        k = bisect_right(tails, x)
        if k == len(tails):
            tails.append(x)
            tail_at.append(i)
        else:
            tails[k] = x
            tail_at[k] = i
        prev[i] = tail_at[k - 1] if k > 0 else -1
    out = []
    i = tail_at[-1] if tail_at else -1
    while i >= 0:
        out.append(i)
        i = int(prev[i])
    return idx[np.array(out[::-1], dtype=np.int64)]


def load_scan_mat(path: str | Path, max_range_m: float = 80.0) -> LaserLog:
    """The Intel data set's ``.mat`` piece: scans, raw odometry and times (no reference)."""
    import scipy.io

    p = Path(path)
    if not p.is_file():
        raise LaserLogError(f"laser .mat file not found: {p}")
    try:
        mat = scipy.io.loadmat(str(p))
    except Exception as exc:  # scipy raises several types for corrupt files
        raise LaserLogError(f"cannot read {p} as a MATLAB file: {exc}") from exc
    missing = [k for k in ("beam_data", "odom", "timestamp") if k not in mat]
    if missing:
        keys = sorted(k for k in mat if not k.startswith("__"))
        raise LaserLogError(f"{p.name} lacks {missing} (it has {keys})")
    ranges = np.asarray(mat["beam_data"], dtype=float)
    odom = np.asarray(mat["odom"], dtype=float)
    t = np.asarray(mat["timestamp"], dtype=float).ravel()
    if ranges.ndim != 2 or odom.shape != (len(ranges), 3) or len(t) != len(ranges):
        raise LaserLogError(
            f"{p.name}: beam_data {ranges.shape}, odom {odom.shape} and timestamp {t.shape} "
            "must have one row per scan (odom: x, y, theta)"
        )
    n = ranges.shape[1]
    start = float(np.ravel(mat.get("beam_start", [-np.pi / 2]))[0])
    end = float(np.ravel(mat.get("beam_end", [np.pi / 2]))[0])
    angles = start + (end - start) / n * np.arange(n)
    bad = ~np.all(np.isfinite(odom), axis=1)
    counts = {"scans": len(t), "bad_odometry": int(bad.sum())}
    keep = ~bad
    t_fixed, repaired = repair_times(t[keep])
    counts["timestamps_repaired"] = repaired
    return LaserLog(t_fixed, ranges[keep], angles, max_range_m, odom[keep],
                    source=p.name, counts=counts)  # fmt: skip


def match_keyframes(
    ranges: np.ndarray, key_ranges: list[np.ndarray], decimals: int = 2
) -> np.ndarray:
    """For each keyframe, the index of the scan with the same range vector (rounded to
    ``decimals``; matches taken in order, so a keyframe never maps before the previous
    one), or -1 when none matches."""
    table: dict[bytes, list[int]] = {}
    r = np.round(np.asarray(ranges, dtype=float), decimals)
    for i, row in enumerate(r):
        table.setdefault(row.tobytes(), []).append(i)
    out = np.full(len(key_ranges), -1, dtype=np.int64)
    last = -1
    for k, kr in enumerate(key_ranges):
        kr = np.round(np.asarray(kr, dtype=float), decimals)
        if kr.shape != r.shape[1:]:
            continue
        cands = table.get(kr.tobytes(), [])
        j = next((c for c in cands if c > last), None)
        if j is not None:
            out[k] = j
            last = j
    return out


def densify(odom: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Reference poses at every row of ``odom`` (N, 3) from ``known`` (N, 3; NaN rows
    where no corrected pose is known); see the module doc. All NaN if none is known."""
    odom = np.asarray(odom, dtype=float)
    known = np.asarray(known, dtype=float)
    have = np.flatnonzero(np.all(np.isfinite(known), axis=1))
    if len(have) == 0:
        return np.full_like(odom, np.nan)
    # C such that known = C (+) odom: C = known (+) (-odom).
    c_th = known[have, 2] - odom[have, 2]
    c, s = np.cos(c_th), np.sin(c_th)
    ox, oy = odom[have, 0], odom[have, 1]
    c_x = known[have, 0] - (c * ox - s * oy)
    c_y = known[have, 1] - (s * ox + c * oy)
    c_th = np.unwrap(c_th)
    dist = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(odom[:, :2], axis=0).T))])
    # Travel is the interpolation variable; where the robot stands still, use the index.
    u = dist + 1e-6 * np.arange(len(dist))
    cx, cy, cth = (np.interp(u, u[have], v) for v in (c_x, c_y, c_th))
    out = compose(np.column_stack([cx, cy, cth]), odom)
    out[:, 2] = wrap(out[:, 2])
    out[have] = known[have]
    out[have, 2] = wrap(out[have, 2])
    return out


def reference_error(reference: np.ndarray, odom: np.ndarray) -> float:
    """Largest position gap between two trajectories after aligning their first poses
    (how far the odometry drifts from the reference)."""
    if len(odom) == 0:
        return 0.0
    rel = relative(odom[:1], odom)
    aligned = compose(np.broadcast_to(reference[:1], rel.shape), rel)
    return float(np.nanmax(np.hypot(*(aligned[:, :2] - reference[:, :2]).T)))


def attach_reference(
    log: LaserLog, key_ranges: list[np.ndarray], key_poses: np.ndarray, source: str = ""
) -> LaserLog:
    """``log`` with reference poses at every scan from a corrected log's keyframes: the
    keyframes are matched to the scans by their range vectors (:func:`match_keyframes`)
    and the reference filled in between (:func:`densify`). LaserLogError when none match."""
    idx = match_keyframes(log.ranges, key_ranges)
    ok = idx >= 0
    if not ok.any():
        raise LaserLogError(
            f"none of the {len(key_ranges)} keyframes of {source or 'the reference'} matches "
            f"a scan of {log.source}: not the same run?"
        )
    known = np.full((len(log), 3), np.nan)
    known[idx[ok]] = np.asarray(key_poses, dtype=float)[ok]
    counts = dict(log.counts)
    counts["keyframes"] = len(key_ranges)
    counts["keyframes_matched"] = int(ok.sum())
    return LaserLog(log.t_s, log.ranges, log.angles, log.max_range_m, log.odom,
                    densify(log.odom, known), log.laser_on_robot, log.source,
                    f"{int(ok.sum())} keyframes of {source}, odometry ramped in between",
                    counts)  # fmt: skip
