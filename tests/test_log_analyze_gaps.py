"""hilnav analyze scores no instant inside a gap of the truth (msgs.GroundTruth
gap_before_s: a data set's motion capture lost the robot)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hilnav.analysis.analyze import analyze
from hilnav.analysis.report import summary_json
from hilnav.analysis.tracks import Track
from hilnav.log.writer import LogWriter
from msgs import GroundTruth, Interval, Pose2D, PoseBox, PoseEstimate

S = 1_000_000_000
MS = 1_000_000


def test_covered_excludes_the_inside_of_each_gap_only() -> None:
    tr = Track(gaps=[(10, 20), (30, 35)])
    t = np.array([5, 10, 11, 19, 20, 25, 31, 40])
    assert tr.covered(t).tolist() == [True, True, False, False, True, True, False, True]


def test_estimates_inside_a_truth_gap_are_not_scored(tmp_path: Path) -> None:
    """Truth at 10 Hz on a straight line, lost from 2 s to 4 s. The estimate is exact
    except inside the gap, where it is 5 m off (what a linear interpolation across the
    gap could not judge anyway); boxes likewise."""
    path = tmp_path / "gap.mcap"
    with LogWriter(path, wall_clock=False) as w:
        for k in range(61):
            t = k * 100 * MS
            x = 0.1 * k
            if not (2 * S < t < 4 * S):
                gap = 2.0 if t == 4 * S else 0.0
                w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(x, 0, 0), gap_before_s=gap), t)
            off = 5.0 if 2 * S < t < 4 * S else 0.0
            cov = (0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01)
            w.write("/r1/pose", PoseEstimate(t, Pose2D(x + off, 0, 0), cov), t)
            box = PoseBox(t, "r1", Interval(x + off - 0.1, x + off + 0.1), Interval(-0.1, 0.1),
                          Interval(-0.1, 0.1))  # fmt: skip
            w.write("/r1/pose_box", box, t)
    ra = analyze(path).robots["r1"]
    assert ra.paths["pose"].samples == 61 - 19
    assert ra.paths["pose"].position.error_m.max == pytest.approx(0.0, abs=1e-9)
    assert ra.cp_boxes.containment.judged == 61 - 19
    assert ra.cp_boxes.containment.contained_fraction == 1.0
    assert ra.ekf_3sigma["pose"].poses == 61 - 19
    assert ra.ekf_3sigma["pose"].contained_fraction == 1.0
    gaps = summary_json(analyze(path))["robots"]["r1"]["truth_gaps"]
    assert gaps == {"count": 1, "total_s": 2.0, "longest_s": 2.0}
