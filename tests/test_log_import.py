"""hilnav import victoria-park: the real data set into a log that replay and analyze read."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hilnav.log.reader import ReadStats, read_messages, read_metadata
from tests.conftest import HILNAV, ROOT, hilnav_env

DURATION_S = 30.0


@pytest.fixture(scope="module")
def vp_dir() -> Path:
    from tests.conftest import SHARED

    d = SHARED / "data" / "victoria_park"
    if not (d / "aa3_dr.mat").is_file():
        pytest.skip(f"Victoria Park data not found in {d}")
    return d


def test_import_first_seconds_matches_the_loader(vp_dir: Path, tmp_path: Path) -> None:
    from mapping.slam.victoria_park import load_victoria_park
    from msgs.landmarks import LandmarkScan, VehicleControl

    out = tmp_path / "vp.mcap"
    proc = subprocess.run(
        [*HILNAV, "import", "victoria-park", str(vp_dir), str(out), "--duration", str(DURATION_S)],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    data = load_victoria_park(vp_dir)
    t0 = min(data.dr_time_s[0], data.scan_time_s[0], data.gps_time_s[0])
    t_end_ns = round(t0 * 1e9) + int(DURATION_S * 1e9)

    def n(ts: np.ndarray) -> int:
        return int(sum(round(t * 1e9) <= t_end_ns for t in ts))

    expected = {
        "control": n(data.dr_time_s),
        "landmark_scan": n(data.scan_time_s),
        "gps": n(data.gps_time_s),
    }
    assert report["messages"] == expected
    stats = ReadStats()
    got = list(read_messages(out, stats=stats))
    assert stats.unknown == 0 and stats.malformed == 0
    assert len(got) == sum(expected.values())
    times = [m.log_time_ns for m in got]
    assert times == sorted(times)
    controls = [m.msg for m in got if m.topic == "/vp/control"]
    assert isinstance(controls[0], VehicleControl)
    assert controls[10].speed_mps == pytest.approx(data.speed_mps[10])
    assert controls[10].steering_rad == pytest.approx(data.steering_rad[10])
    scans = [m.msg for m in got if m.topic == "/vp/landmark_scan"]
    assert isinstance(scans[0], LandmarkScan) and scans[0].bearing_zero == "y"
    assert np.allclose(scans[3].ranges_m, data.scans[3][0])
    meta = read_metadata(out)["hilnav"]
    assert meta["dataset"] == "victoria_park" and meta["robot"] == "vp"

    # analyze understands it: the GPS is the reference
    proc = subprocess.run(
        [*HILNAV, "analyze", str(out), "--out", str(tmp_path / "a"), "--no-plots", "--json"],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    vp = summary["robots"]["vp"]
    assert vp["reference"] == "gps" and vp["topics"]["landmark_scan"] == expected["landmark_scan"]


def test_import_of_a_missing_folder_is_a_clear_error(tmp_path: Path) -> None:
    proc = subprocess.run(
        [*HILNAV, "import", "victoria-park", str(tmp_path / "nothing"), str(tmp_path / "o.mcap")],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2
    assert "not found" in proc.stderr and "Traceback" not in proc.stderr
    # ... and where the data set comes from, for a clone without ../shared
    for words in ("ACFR", "aa3_dr.mat", "aa3_gpsx.mat", "VictoriaParkSinSincronizar.mat"):
        assert words in proc.stderr
    assert "shared/data/victoria_park" in proc.stderr and "victoria_park.htm" in proc.stderr


def test_replay_runs_ekf_slam_on_it_deterministically(vp_dir: Path, tmp_path: Path) -> None:
    src = tmp_path / "vp.mcap"
    proc = subprocess.run(
        [*HILNAV, "import", "victoria-park", str(vp_dir), str(src), "--duration", str(DURATION_S)],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    reports = []
    for name in ("a.mcap", "b.mcap"):
        proc = subprocess.run(
            [*HILNAV, "replay", str(src), "--out", str(tmp_path / name)],
            capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=240,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        reports.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()
    rep = reports[0]
    assert rep["config"].startswith("landmark-slam") and rep["pipeline_errors"] == 0
    assert rep["outputs"]["pose"] == rep["fed"]["control"] + rep["fed"]["landmark_scan"]
    proc = subprocess.run(
        [*HILNAV, "analyze", str(tmp_path / "a.mcap"), "--out", str(tmp_path / "an"), "--no-plots",
         "--json"],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    vp = json.loads(proc.stdout.strip().splitlines()[-1])["robots"]["vp"]
    assert vp["reference"] == "gps" and vp["landmarks"]["count"] >= 10
    # EKF-SLAM against GPS (its own frame: after the best rigid fit); the GPS itself is
    # good to a few metres at best
    assert vp["paths"]["pose"]["position_error_after_rigid_fit_m"]["rms"] < 3.0
