"""The MRCLAM loader on the real Dataset 6 and on broken run directories."""

from __future__ import annotations

import numpy as np
import pytest

from localization.mrclam import MrclamError, load_mrclam
from tests.conftest import SHARED, require

DATA = SHARED / "data/mrclam/MRCLAM_Dataset6"


def test_dataset6_loads_with_subjects_and_truth():
    run = load_mrclam(require(DATA))
    assert sorted(run.robots) == [1, 2, 3, 4, 5]
    assert sorted(run.landmarks) == list(range(6, 21))
    assert 880 < run.end_s - run.start_s < 900
    for robot in run.robots.values():
        subjects = set(robot.measurements[:, 1].astype(int))
        assert subjects <= set(range(1, 21)) and robot.subject not in subjects
        assert np.all(np.diff(robot.odometry[:, 0]) >= 0)
    # A few measurements name barcodes that the table does not hold: counted, not guessed.
    assert sum(run.dropped.values()) == 6


def test_truth_interpolates_heading_through_the_short_arc_and_flags_gaps(tmp_path):
    d = tmp_path / "run"
    d.mkdir()
    (d / "Barcodes.dat").write_text("# c\n1 5\n6 27\n")
    (d / "Landmark_Groundtruth.dat").write_text("6 1.0 2.0 0.001 0.001\n")
    (d / "Robot1_Odometry.dat").write_text("0.0 0.1 0.0\n1.0 0.1 0.0\n")
    (d / "Robot1_Measurement.dat").write_text("0.5 27 2.0 0.1\n0.6 99 2.0 0.1\n")
    (d / "Robot1_Groundtruth.dat").write_text("0.0 0 0 3.1\n0.1 0 0 -3.1\n5.0 1 0 0\n")
    run = load_mrclam(d)
    r = run.robots[1]
    assert r.measurements.tolist() == [[0.5, 6.0, 2.0, 0.1]]
    assert run.dropped["robot1_unknown_barcode"] == 1
    pose, ok = r.truth_at(np.array([0.05, 2.0, 5.0, 6.0]))
    assert abs(abs(pose[0, 2]) - np.pi) < 1e-9  # through pi, not through 0
    assert ok.tolist() == [True, False, True, False]


def test_broken_directories_get_a_clear_error(tmp_path):
    with pytest.raises(MrclamError, match="not a directory"):
        load_mrclam(tmp_path / "nope")
    with pytest.raises(MrclamError, match="Barcodes.dat: missing"):
        load_mrclam(tmp_path)
    (tmp_path / "Barcodes.dat").write_text("1 5\n")
    (tmp_path / "Landmark_Groundtruth.dat").write_text("6 1.0 2.0 x 0.1\n")
    with pytest.raises(MrclamError, match="numeric columns"):
        load_mrclam(tmp_path)
