"""``bench/ir_tolerance.py``: the IR map's scores against pose errors of the robot's own
shape, scaled (a slice of the Intel log for the whole bench)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bench.ir_tolerance import crossing, scaled
from tests.conftest import ROOT, SHARED, hilnav_env

INTEL = SHARED / "data" / "intel"


def test_scaled_error_keeps_the_error_shape_and_wraps_the_heading() -> None:
    ref = np.array([[0.0, 0.0, 3.0], [1.0, 0.0, -2.9], [2.0, 1.0, 0.0]])
    traj = np.array([[0.2, -0.4, -3.0], [1.0, 1.0, 3.0], [2.0, 1.0, 0.2]])
    np.testing.assert_allclose(scaled(traj, ref, 0.0), ref)
    one = scaled(traj, ref, 1.0)
    np.testing.assert_allclose(one[:, :2], traj[:, :2])
    np.testing.assert_allclose(np.cos(one[:, 2] - traj[:, 2]), 1.0)
    half = scaled(traj, ref, 0.5)
    np.testing.assert_allclose(half[:, :2], 0.5 * (ref[:, :2] + traj[:, :2]))
    # 3.0 -> -3.0 is a turn of 2 pi - 6 = 0.283 rad through pi, not -6 rad through 0
    assert half[0, 2] == pytest.approx(3.0 + 0.5 * (2 * math.pi - 6.0))
    assert half[1, 2] == pytest.approx(-2.9 - 0.5 * (2 * math.pi - 5.9))
    assert half[2, 2] == pytest.approx(0.1)


def test_crossing_interpolates_where_both_scores_fall_below_the_level() -> None:
    err = [0.0, 1.0, 2.0]
    # the lower of the two falls below 0.5 between 1 and 2: 0.6 -> 0.2, a quarter along
    assert crossing(err, [0.9, 0.6, 0.2], [0.95, 0.7, 0.4]) == pytest.approx(1.25)
    assert crossing(err, [0.9, 0.8, 0.7], [0.9, 0.8, 0.6]) == 2.0  # never below
    assert math.isnan(crossing(err, [0.4, 0.3, 0.2], [0.9, 0.8, 0.7]))  # below at once


def test_ir_tolerance_bench_on_a_slice(shared_dir: Path) -> None:
    """On 600 scans: at f = 0 the map is the reference's (no pose error, its precision),
    and the scores fall as the error grows."""
    proc = subprocess.run(
        ["python3", str(ROOT / "bench" / "ir_tolerance.py"), str(INTEL), "--scans", "600",
         "--seeds", "1", "--fractions", "0,0.5,1"],
        capture_output=True, text=True, timeout=300, env=hilnav_env(),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    rep = json.loads(lines[-1])
    assert rep["scans"] == 600 and rep["mounts"] == 6
    assert set(rep["pose_err_for_pr50_by_shape_m"]) == {"odometry", "gyro 1"}
    rows = [ln.split() for ln in lines[2:-1]]
    odo = [(float(r[-4]), float(r[-3]), float(r[-2])) for r in rows if r[0] == "odometry"]
    assert (
        len(odo) == 3
        and odo[0][0] == 0.0
        and odo[0][1] == pytest.approx(rep["precision_ref"], abs=5e-4)
    )
    assert odo[0][0] < odo[1][0] < odo[2][0]  # the mean pose error grows with f
    assert odo[2][1] < odo[0][1] and odo[2][2] < odo[0][2]
