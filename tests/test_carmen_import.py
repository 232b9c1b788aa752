"""CARMEN laser logs: the loader, the IR sensors emulated from the laser, and
``hilnav import carmen`` round-tripped through replay (a slice of the Intel log)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fakes.world import IrErrorModel
from fakes.world.laser_ir import LaserIrBoard, ir_ranges_from_laser
from hilnav.log.reader import read_messages, read_metadata
from mapping.carmen import load_carmen, load_laser_log
from mapping.laser_log import densify, laser_angles, repair_times
from tests.conftest import HILNAV, ROOT, SHARED, hilnav_env, require

INTEL = SHARED / "data" / "intel"
MAT = INTEL / "sot_scan_intel.mat"
GFS = INTEL / "intel.gfs.log"
DEG = math.pi / 180.0


def _flaser(ranges, pose, odom, t) -> str:
    r = " ".join(f"{v:.3f}" for v in ranges)
    p = " ".join(f"{v:.6f}" for v in (*pose, *odom))
    return f"FLASER {len(ranges)} {r} {p} {t:.6f} host {t:.6f}"


def test_carmen_lines_bad_lines_resets_and_repaired_times(tmp_path: Path) -> None:
    # A corrected (GMapping-style) log: ODOM is the corrected odometry with an unstamped
    # reset line at the keyframe; one ODOM stamp is late; two lines are garbage.
    c1 = (3.5 + math.cos(0.1), 0.5 + math.sin(0.1), 0.1)
    lines = [
        "# comment",
        "PARAM robot_name pippo",
        "ODOM 0 0 0 0 0 0 1.0 h 1.0",
        "ODOM 1.0 0 0 0 0 0 2.0 h 2.0",
        "ODOM 2.0 0 0 0 0 0 9.0 h 9.0",  # stamp 6 s late: repaired to 3.0
        _flaser([2.0] * 180, (2.0, 0, 0), (2.0, 0, 0), 3.0),
        "ODOM 3.0 0 0 0 0 0 4.0 h 4.0",
        "ODOM 3.5 0.5 0.1 0 0 0 0 h 0",  # reset to the corrected pose: no stamp
        _flaser([2.0] * 180, (3.5, 0.5, 0.1), (3.5, 0.5, 0.1), 4.0),
        "ODOM {:.6f} {:.6f} 0.1 0 0 0 5.0 h 5.0".format(*c1),
        "ODOM 1 2 three 0 0 0 5.5 h 5.5",  # not a number
        "FLASER 180 1 2 3",  # too short
        _flaser([3.0] * 180, c1, c1, 5.0),
    ]
    f = tmp_path / "run.gfs.log"
    f.write_text("\n".join(lines) + "\n")
    log = load_carmen(f)
    c = log.counts
    assert c["bad_lines"] == 2 and c["odometry_resets"] == 1 and c["scans"] == 3
    assert c["timestamps_repaired"] == 1
    assert log.reference is not None and "corrected" in log.reference_source
    np.testing.assert_allclose(log.reference, [[2, 0, 0], [3.5, 0.5, 0.1], c1], atol=1e-6)
    # Raw odometry: the jump into the reset line is left out, the motion after it kept.
    np.testing.assert_allclose(log.odom, [[2, 0, 0], [3, 0, 0], [4, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(np.degrees(log.angles[[0, 90, 179]]), [-90, 0, 89])
    assert load_carmen(f, poses="odometry").reference is None
    with pytest.raises(ValueError, match="no laser scans"):
        (tmp_path / "empty.log").write_text("ODOM 0 0 0 0 0 0 1 h 1\n")
        load_carmen(tmp_path / "empty.log")


def test_robotlaser1_and_raw_logs_are_odometry_without_reference(tmp_path: Path) -> None:
    n = 5
    r = " ".join(["1.5"] * n)
    line = (f"ROBOTLASER1 0 -1.5708 3.1416 0.7854 8.0 0.01 0 {n} {r} 0 "
            "0.1 0 0 0 0 0 0 0 0 0 0 {t} h {t}")  # fmt: skip
    f = tmp_path / "raw.log"
    f.write_text("\n".join(line.format(t=t) for t in (1.0, 2.0, 3.0)) + "\n")
    log = load_carmen(f)
    assert log.reference is None and log.max_range_m == 8.0
    assert log.laser_on_robot == pytest.approx((0.1, 0.0, 0.0))
    np.testing.assert_allclose(log.angles, -1.5708 + 0.7854 * np.arange(n))


def test_repair_times_and_densify() -> None:
    t, n = repair_times(np.array([0.0, 1.0, 5.0, 2.0, 3.0, 1.5, 4.0]))
    assert n == 2 and np.all(np.diff(t) >= 0)
    np.testing.assert_allclose(t, [0, 1, 1.5, 2, 3, 3.5, 4])
    # Odometry along x with a heading error growing; corrections known at both ends.
    odom = np.column_stack([np.linspace(0, 4, 5), np.zeros(5), np.zeros(5)])
    known = np.full((5, 3), np.nan)
    known[0] = [1.0, 1.0, 0.0]
    known[4] = [1.0, 5.0, math.pi / 2]
    ref = densify(odom, known)
    np.testing.assert_allclose(ref[[0, 4]], known[[0, 4]], atol=1e-12)
    assert ref[2, 2] == pytest.approx(math.pi / 4)  # the correction ramped in halfway


def test_ir_from_laser_wall_edges_and_unknown() -> None:
    # A wall at x = 3 m in front of a laser at the robot centre (-90..+89 deg).
    ang = laser_angles(180)
    ranges = np.where(np.abs(ang) < 80 * DEG, 3.0 / np.cos(ang), 80.0)[None, :]
    mounts = np.array([[0.2, 0.0, 0.0], [0.2, 0.1, 20 * DEG], [0.0, 0.0, math.pi],
                       [0.0, 0.19, 89.5 * DEG]])  # fmt: skip
    r = ir_ranges_from_laser(ranges, ang, 80.0, mounts)[0]
    assert r[0] == pytest.approx(2.8, abs=0.01)
    assert r[1] == pytest.approx((3.0 - 0.2) / math.cos(20 * DEG), abs=0.02)
    assert math.isnan(r[2])  # behind: the laser cannot tell
    assert math.isinf(r[3])  # the laser saw that ray free (no return beyond 80 deg)
    s = LaserIrBoard(4).scan(r, 5)
    assert s.status == ("ok", "ok", "invalid", "too_far")
    noisy = LaserIrBoard(4, noise=IrErrorModel(), median_window=1, seed=3).scan(r, 5)
    assert noisy.status[2] == "invalid" and noisy.ranges_m[0] == pytest.approx(2.8, abs=0.3)


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    require(MAT), require(GFS)
    out = tmp_path_factory.mktemp("carmen") / "intel.mcap"
    proc = subprocess.run(
        [*HILNAV, "import", "carmen", str(MAT), str(out), "--reference", str(GFS),
         "--scans", "300", "--gyro-seed", "1", "--ir-mounts", "0.2,0,0;0.1,0.15,60;0,-0.2,-90"],
        capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout.strip().splitlines()[-1])
    assert rep["messages"]["ir"] == 300 and rep["messages"]["truth"] == 300
    assert rep["messages"]["reference_map"] == 1 and rep["messages"]["gyro"] > 5000
    return out


def test_import_round_trip_matches_the_loader(imported: Path) -> None:
    from hilnav.importers.carmen import emulate

    log = load_laser_log(MAT, GFS).head(300)
    mounts = np.array([[0.2, 0, 0], [0.1, 0.15, 60 * DEG], [0, -0.2, -90 * DEG]])
    run = emulate(log, mounts, gyro_seed=1)
    msgs = {"ir": [], "truth": [], "odometry": []}
    for m in read_messages(imported):
        kind = m.topic.rsplit("/", 1)[-1]
        if kind in msgs:
            msgs[kind].append(m.msg)
    assert [s.status for s in msgs["ir"]] == [s.status for s in run.scans]
    np.testing.assert_array_equal([s.ranges_m for s in msgs["ir"]], [s.ranges_m for s in run.scans])
    assert [s.stamp_ns for s in msgs["ir"]] == [s.stamp_ns for s in run.scans]
    assert msgs["truth"] == run.truth
    assert [o.pose for o in msgs["odometry"]] == [o.pose for o in run.odometry]
    meta = read_metadata(imported)["hilnav"]
    assert meta["pipeline"] == "daemon" and "[0.1000, 0.1500, 60.000]" in meta["config_toml"]


def test_replay_maps_it_and_analyze_scores_it(imported: Path, tmp_path: Path) -> None:
    from hilnav.analysis.analyze import analyze
    from hilnav.replay.replayer import replay

    out = tmp_path / "replayed.mcap"
    rep = replay(imported, out, progress=False)
    assert rep.pipeline_errors == 0 and rep.outputs["map"] >= 1 and rep.outputs["heading"] == 300
    # the run's last word: the final map (the association's pose graph solved), logged
    # at the last input's log time and stamped at the last scan
    maps = [m for m in read_messages(out) if m.topic == "/intel/map"]
    last_ir = [m for m in read_messages(imported) if m.topic == "/intel/ir"][-1]
    fed = [m.log_time_ns for m in read_messages(imported) if m.topic.rsplit("/", 1)[-1]
           in ("odometry", "gyro", "ir", "gps")]  # fmt: skip
    assert maps[-1].publish_time_ns == last_ir.msg.stamp_ns and maps[-1].log_time_ns == max(fed)
    ra = analyze(out).robots["intel"]
    assert ra.reference == "truth"
    assert ra.paths["heading"].position.error_m.mean < 0.3
    assert ra.map is not None and ra.map.scores is not None
    assert ra.map.scores.occupied_precision > 0.3 and ra.heading_consistency is not None


def test_ir_real_bench_on_a_slice_with_other_mounts(shared_dir: Path) -> None:
    """``bench/ir_real.py`` on 600 scans with a three-sensor layout: every figure of its
    last line is there, and the true-heading floor (odometry distances along the
    reference heading) is the odometry's distance error: zero only at the start."""
    proc = subprocess.run(
        ["python3", str(ROOT / "bench" / "ir_real.py"), str(INTEL), "--scans", "600",
         "--seeds", "1", "--no-encoders-only", "--mounts", "0.2,0,0;0.1,0.15,60;0,-0.2,-90"],
        capture_output=True, text=True, timeout=300, env=hilnav_env(),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    rep = json.loads(lines[-1])
    assert rep["mounts"] == 3 and rep["scans"] == 600 and rep["seeds"] == 1
    assert any(line.startswith("true heading") for line in lines)
    for key in ("pose_err_true_heading_m", "pose_err_noda_m", "pose_err_da_median_m",
                "precision_true_heading", "precision_da_median", "recall_da_median",
                "shape_err_noda_m", "shape_err_da_median_m", "rel_err_noda_m",
                "rel_err_da_median_m", "shape_err_true_heading_m"):  # fmt: skip
        assert rep[key] is not None and math.isfinite(rep[key]), key
    assert 0.0 < rep["pose_err_true_heading_m"] < 1.0  # 16 m of a real robot's odometry
    assert rep["precision_true_heading"] <= rep["precision_ref"]
    # the fit can only lower the error; the relative error is that of 10 m stretches
    assert 0.0 < rep["shape_err_true_heading_m"] <= rep["pose_err_true_heading_m"]
    assert 0.0 < rep["rel_err_true_heading_m"] < 1.0
    assert rep["shape_worse_runs"] in (0, 1)


def test_true_heading_floor_is_exact_when_the_odometry_is(
    shared_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The floor composes the odometry's steps along the reference heading: with the
    reference poses as the odometry it gives them back."""
    import importlib.util
    from dataclasses import replace

    from hilnav.importers.carmen import emulate

    spec = importlib.util.spec_from_file_location("ir_real", ROOT / "bench" / "ir_real.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "ir_real", bench)  # its dataclasses look it up
    spec.loader.exec_module(bench)
    log = load_laser_log(MAT, GFS).head(400)
    run = emulate(log, np.array([[0.2, 0.0, 0.0]]))
    from msgs import Pose2D

    exact = [
        replace(o, pose=Pose2D(*map(float, p)))
        for o, p in zip(run.odometry, log.reference, strict=True)
    ]
    run_exact = replace(run, odometry=exact)
    got = np.array([[p.x, p.y, p.theta] for p in bench.true_heading_poses(run_exact)])
    np.testing.assert_allclose(got[:, :2], log.reference[:, :2], atol=1e-9)
    real = np.array([[p.x, p.y] for p in bench.true_heading_poses(run)])
    assert np.hypot(*(real - log.reference[:, :2]).T).max() > 0.01  # the log's distance error


def test_odometry_scale_bench_measures_the_scale_ahead(shared_dir: Path) -> None:
    """``bench/odometry_scale.py``: the plane two forward beams see gives its distance and
    normal exactly; on the Intel log's first 4,000 scans the clean stretches (a wall ahead
    over a metre) give the reference's distance per odometry distance within 2 %; a
    layout without two beams ahead finds none."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "odometry_scale", ROOT / "bench" / "odometry_scale.py"
    )
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    mounts = np.array([[0.2, 0.05, 15 * DEG], [0.2, -0.05, -15 * DEG], [0.0, 0.2, 90 * DEG]])
    assert bench.front_pair(mounts) == (1, 0)
    # a wall across the heading 3 m ahead (x = 3 in the robot frame): D = 3, normal at 0
    ranges = np.array([(3.0 - 0.2) / np.cos(15 * DEG)] * 2 + [1.0])
    dist, angle = bench.plane(mounts, ranges, 1, 0)
    assert dist == pytest.approx(3.0) and angle == pytest.approx(0.0, abs=1e-12)
    assert bench.front_pair(mounts[[0, 2]]) is None
    for argv, clean in (([str(INTEL), "--scans", "4000"], True),
                        ([str(INTEL), "--scans", "4000", "--mounts", "0.2,0,0;0,0.2,90"], False)):  # fmt: skip
        proc = subprocess.run(["python3", str(ROOT / "bench" / "odometry_scale.py"), *argv],
                              capture_output=True, text=True, timeout=120, env=hilnav_env())  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        rep = json.loads(proc.stdout.strip().splitlines()[-1])
        if clean:
            assert rep["events_clean"] >= 1 and rep["k_err_median_clean"] < 0.02
        else:
            assert rep["front_pair"] is None and rep["events"] == 0
