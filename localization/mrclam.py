"""Loader of a UTIAS MRCLAM run (Leung, Halpern, Barfoot, Liu, IJRR 30(8), 2011).

An MRCLAM run directory holds text files with ``#`` comment lines and whitespace-separated
columns (``shared/data/mrclam/README.md``):

- ``Barcodes.dat``: subject # (1-5 robots, 6-20 landmarks) -> barcode #;
- ``Landmark_Groundtruth.dat``: subject #, x, y [m], std-dev x, y [m];
- ``RobotN_Odometry.dat``: time [s], forward velocity [m/s], angular velocity [rad/s]
  (commanded velocities, about 67 Hz);
- ``RobotN_Measurement.dat``: time [s], BARCODE #, range [m], bearing [rad] (camera,
  to landmarks and to the other robots);
- ``RobotN_Groundtruth.dat``: time [s], x, y [m], heading [rad] (motion capture, ~100 Hz,
  gaps of up to a few seconds).

``load_mrclam`` reads them into numpy arrays, translates barcodes to subjects (unknown
barcodes are counted and dropped, never guessed), and keeps the data set's own clock
(seconds). ``truth_at`` interpolates the motion-capture truth (heading through the
shortest arc, ``numerics.angles.wrap``) and flags instants that fall in a gap longer than
``max_gap_s``: those instants have no truth and must not be scored. Reading files is the
only I/O here; no clocks, no globals.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from numerics.angles import wrap

BARCODES_FILE = "Barcodes.dat"
LANDMARKS_FILE = "Landmark_Groundtruth.dat"
#: Largest gap (s) in the motion-capture truth across which it is interpolated.
MAX_TRUTH_GAP_S = 0.25
_ROBOT_FILE = re.compile(r"Robot(\d+)_Odometry\.dat$")


class MrclamError(ValueError):
    """An MRCLAM file is missing or holds lines that are not the expected columns."""


@dataclass(frozen=True)
class RobotRun:
    """One robot's streams (seconds on the data set's clock, metres, radians)."""

    subject: int
    #: (N, 3): time, forward velocity v, angular velocity w (commanded).
    odometry: np.ndarray = field(repr=False)
    #: (M, 4): time, SUBJECT # (barcode translated), range, bearing.
    measurements: np.ndarray = field(repr=False)
    #: (K, 4): time, x, y, heading (motion capture).
    truth: np.ndarray = field(repr=False)

    def truth_at(
        self, t: np.ndarray | float, max_gap_s: float = MAX_TRUTH_GAP_S
    ) -> tuple[np.ndarray, np.ndarray]:
        """Truth (x, y, heading) at ``t`` and a mask of instants that have a truth.

        An instant has a truth when it lies inside the truth's span and the two truth
        samples around it are at most ``max_gap_s`` apart (or it hits a sample exactly).
        """
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        ts = self.truth[:, 0]
        i = np.clip(np.searchsorted(ts, tt), 1, len(ts) - 1)
        t0, t1 = ts[i - 1], ts[i]
        span = t1 - t0
        frac = np.where(span > 0, (tt - t0) / np.where(span > 0, span, 1.0), 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        a, b = self.truth[i - 1, 1:], self.truth[i, 1:]
        xy = a[:, :2] + (b[:, :2] - a[:, :2]) * frac[:, None]
        th = wrap(a[:, 2] + wrap(b[:, 2] - a[:, 2]) * frac)
        ok = (tt >= ts[0]) & (tt <= ts[-1]) & ((span <= max_gap_s) | (tt == t0) | (tt == t1))
        return np.column_stack([xy, th]), ok


@dataclass(frozen=True)
class MrclamRun:
    """A whole run: robots by subject #, landmarks by subject #, and what was dropped."""

    directory: str
    robots: dict[int, RobotRun]
    #: subject # -> (x, y, std-dev x, std-dev y)
    landmarks: dict[int, tuple[float, float, float, float]]
    barcodes: dict[int, int]  # barcode # -> subject #
    dropped: Counter = field(default_factory=Counter)

    @property
    def start_s(self) -> float:
        return min(float(r.odometry[0, 0]) for r in self.robots.values())

    @property
    def end_s(self) -> float:
        return max(float(r.odometry[-1, 0]) for r in self.robots.values())


def _table(path: Path, columns: int) -> np.ndarray:
    """The numeric rows of ``path`` (comment lines skipped) as an (n, columns) array."""
    if not path.is_file():
        raise MrclamError(f"{path}: missing (an MRCLAM run directory holds it)")
    try:
        data = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as exc:
        raise MrclamError(f"{path}: not {columns} numeric columns per line ({exc})") from None
    if data.size == 0:
        return np.empty((0, columns))
    if data.shape[1] != columns:
        raise MrclamError(f"{path}: {data.shape[1]} columns per line, expected {columns}")
    if not np.all(np.isfinite(data)):
        raise MrclamError(f"{path}: holds values that are not finite numbers")
    return data


def _sorted(a: np.ndarray) -> np.ndarray:
    return a[np.argsort(a[:, 0], kind="stable")] if len(a) else a


def robot_subjects(directory: str | Path) -> list[int]:
    """The robots' subject numbers that have a ``RobotN_Odometry.dat`` in ``directory``."""
    d = Path(directory)
    return sorted(int(m.group(1)) for p in d.iterdir() if (m := _ROBOT_FILE.match(p.name)))


def load_mrclam(directory: str | Path, robots: list[int] | None = None) -> MrclamRun:
    """Read an MRCLAM run directory (all robots found, or only ``robots``)."""
    d = Path(directory)
    if not d.is_dir():
        raise MrclamError(f"{d}: not a directory (an MRCLAM run directory is expected)")
    codes = _table(d / BARCODES_FILE, 2)
    barcodes = {int(b): int(s) for s, b in codes}
    marks = _table(d / LANDMARKS_FILE, 5)
    landmarks = {int(r[0]): (float(r[1]), float(r[2]), float(r[3]), float(r[4])) for r in marks}
    found = robot_subjects(d)
    subjects = found if robots is None else list(robots)
    if not subjects:
        raise MrclamError(f"{d}: no RobotN_Odometry.dat files")
    dropped: Counter = Counter()
    runs: dict[int, RobotRun] = {}
    for n in subjects:
        odo = _sorted(_table(d / f"Robot{n}_Odometry.dat", 3))
        meas = _sorted(_table(d / f"Robot{n}_Measurement.dat", 4))
        truth = _sorted(_table(d / f"Robot{n}_Groundtruth.dat", 4))
        if len(odo) < 2 or len(truth) < 2:
            raise MrclamError(f"{d}: robot {n} has fewer than two odometry or truth samples")
        subj = np.array([barcodes.get(int(b), -1) for b in meas[:, 1]], dtype=float)
        unknown = subj < 0
        if unknown.any():
            dropped[f"robot{n}_unknown_barcode"] += int(unknown.sum())
        meas = meas[~unknown].copy()
        meas[:, 1] = subj[~unknown]
        runs[n] = RobotRun(subject=n, odometry=odo, measurements=meas, truth=truth)
    return MrclamRun(str(d), runs, landmarks, barcodes, dropped)
