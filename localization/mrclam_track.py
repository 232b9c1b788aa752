"""The EKF track of one MRCLAM robot (what localization/mrclam_ekf.py's ``run_ekf``
returns) and its score against the motion-capture truth (RMSE, n-sigma containment).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from localization.mrclam import RobotRun
from numerics.angles import wrap


@dataclass
class EkfTrack:
    """One robot's EKF estimates: a row every ``output_period_s`` from the run's start
    (``on_grid``, exact instants: the filter is predicted to them) and one after every
    measurement update of the robot; times on the data set's (and the truth's) clock,
    non-decreasing."""

    robot: int
    t: np.ndarray  # (n,) seconds
    mean: np.ndarray  # (n, 3) x, y, theta (theta continuous)
    cov: np.ndarray  # (n, 3, 3)
    counts: Counter = field(default_factory=Counter)
    #: The measurements the gate refused: (time, subject, NIS).
    gated: list[tuple[float, int, float]] = field(default_factory=list)
    #: (n,) True for the rows of the uniform grid (None: every row).
    on_grid: np.ndarray | None = None

    def sigma(self) -> np.ndarray:
        """(n, 3) standard deviations of x, y, theta."""
        return np.sqrt(np.maximum(np.diagonal(self.cov, axis1=1, axis2=2), 0.0))


def score_track(track: EkfTrack, robot: RobotRun, n_sigma: float = 3.0) -> dict:
    """RMSE and n-sigma containment against the truth at the track's grid instants
    (uniform in time), only where the truth exists (``truth_at``'s mask). The commands
    are shifted by the lag, so the track is on the truth's clock: no further shift.
    Containment: x, y and theta (wrapped) all within n_sigma standard deviations;
    ``containment_xy``: x and y only."""
    rows = np.ones(len(track.t), bool) if track.on_grid is None else track.on_grid
    t, mean, sig = track.t[rows], track.mean[rows], track.sigma()[rows]
    pose, ok = robot.truth_at(t)
    e = mean[ok] - pose[ok]
    e[:, 2] = wrap(e[:, 2])
    inside = np.abs(e) <= n_sigma * sig[ok]
    n = int(ok.sum())
    if not n:
        return {
            "scored": 0,
            "rmse_m": math.nan,
            "heading_rmse_rad": math.nan,
            "containment": math.nan,
            "containment_xy": math.nan,
        }
    return {
        "scored": n,
        "rmse_m": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))),
        "heading_rmse_rad": float(np.sqrt(np.mean(e[:, 2] ** 2))),
        "containment": float(np.mean(inside.all(axis=1))),
        "containment_xy": float(np.mean(inside[:, :2].all(axis=1))),
    }
