"""hilnav analyze on small synthetic logs with known errors (written with LogWriter)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hilnav.analysis.analyze import analyze
from hilnav.analysis.containment import box_contains
from hilnav.analysis.geometry import error_after_rigid_fit, interp_pose, relative_error
from hilnav.analysis.report import digest, summary_json
from msgs import Interval, PoseBox, wrap_angle
from tests.conftest import HILNAV, ROOT, hilnav_env
from tests.logsynth import (
    HEADING_DRIFT_DEG_PER_M,
    ODO_DRIFT_DEG_PER_M,
    POSE_OFFSET_M,
    write_synthetic_log,
)


@pytest.fixture(scope="module")
def synth(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    path = tmp_path_factory.mktemp("synth") / "run.mcap"
    return path, write_synthetic_log(path, seed=1)


def test_path_errors_and_drift_per_metre(synth: tuple[Path, dict]) -> None:
    path, exp = synth
    ra = analyze(path).robots["r1"]
    assert ra.reference == "truth"
    assert ra.reference_distance_m == pytest.approx(exp["distance_m"], rel=1e-6)
    pose = ra.paths["pose"]
    assert pose.position.error_m.mean == pytest.approx(POSE_OFFSET_M, abs=1e-6)
    assert pose.heading.error_deg.max == pytest.approx(0.0, abs=1e-6)
    odo = ra.paths["odometry"].heading.drift
    assert odo.final_deg_per_m == pytest.approx(ODO_DRIFT_DEG_PER_M, rel=0.01)
    assert odo.slope_deg_per_m == pytest.approx(ODO_DRIFT_DEG_PER_M, rel=0.03)
    head = ra.paths["heading"].heading.drift
    assert head.final_deg_per_m == pytest.approx(HEADING_DRIFT_DEG_PER_M, rel=0.01)
    # the heading filter's positions are truth shifted to start at 0: aligned, ~no error
    assert ra.paths["heading"].position.error_m.max < 0.02
    # the drifting odometry wanders off: its position error grows
    assert ra.paths["odometry"].position.error_m.final > 0.3


def test_containment_map_and_diagnostics(synth: tuple[Path, dict]) -> None:
    path, exp = synth
    ra = analyze(path).robots["r1"]
    cp = ra.cp_boxes
    assert cp.boxes == exp["boxes"] and cp.containment.violations == exp["bad_boxes"]
    frac = 1 - exp["bad_boxes"] / exp["boxes"]
    assert cp.containment.contained_fraction == pytest.approx(frac)
    assert cp.median_area_m2 == pytest.approx(0.16)
    assert cp.containment.median_area_m2 == pytest.approx(0.16)  # every box judged
    assert ra.ekf_3sigma["pose"].contained_fraction == pytest.approx(exp["ekf_contained"], abs=0.01)
    assert ra.map.plan == "office"
    assert ra.map.match_ratio == pytest.approx(exp["match_ratio"], abs=1e-6)
    d = ra.diagnostics["arcos"]
    assert d.bad_checksums == 3 and d.connected_fraction == 1.0


def test_without_truth_the_gps_is_the_reference(tmp_path: Path) -> None:
    path = tmp_path / "nogt.mcap"
    write_synthetic_log(path, with_truth=False, with_map=False)
    ra = analyze(path).robots["r1"]
    assert ra.reference == "gps"
    err = ra.paths["pose"].position.error_m
    assert 0.1 < err.mean < 1.5  # GPS noise sigma 0.5 m per axis
    assert ra.paths["pose"].heading is None and ra.cp_boxes is not None
    assert ra.cp_boxes.containment is None and ra.map is None
    # and the JSON summary leaves out what the log does not allow
    s = summary_json(analyze(path))["robots"]["r1"]
    assert "heading_error_deg" not in s["paths"]["pose"] and "cp_boxes" in s
    assert "contained_fraction" not in s["cp_boxes"] and "map" not in s


def test_truncated_log_is_analysed_up_to_its_end(synth: tuple[Path, dict], tmp_path: Path) -> None:
    path, _ = synth
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    a = analyze(cut)
    assert a.read.truncated is True
    assert "r1" in a.robots


def test_box_containment_wraps_theta() -> None:
    box = PoseBox(0, "r1", Interval(0, 1), Interval(0, 1), Interval(3.0, 3.3))
    assert box_contains(box, 0.5, 0.5, -3.1)  # -3.1 + 2 pi = 3.18 in [3.0, 3.3]
    assert not box_contains(box, 0.5, 0.5, 2.9)
    assert not box_contains(box, 1.5, 0.5, 3.1)
    empty = PoseBox(0, "r1", Interval(1, 0), Interval(0, 1), Interval(0, 1))
    assert not box_contains(empty, 0.5, 0.5, 0.5)


def test_interp_heading_across_the_wrap() -> None:
    import numpy as np

    t = np.array([0, 10], dtype=np.int64)
    x, y, th, ok = interp_pose(
        t, np.zeros(2), np.zeros(2), np.array([3.1, -3.1]), np.array([5, 20])
    )
    assert ok.tolist() == [True, False]
    assert abs(wrap_angle(th[0] - np.pi)) < 1e-9  # halfway between 3.1 and -3.1 is pi, not 0


def test_cli_writes_plots_and_summary(synth: tuple[Path, dict], tmp_path: Path) -> None:
    path, exp = synth
    out = tmp_path / "report"
    proc = subprocess.run(
        [*HILNAV, "analyze", str(path), "--out", str(out), "--json"],
        capture_output=True,
        text=True,
        env=hilnav_env(),
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout.strip().splitlines()[-1])
    saved = json.loads((out / "summary.json").read_text())
    assert printed["robots"] == saved["robots"]
    names = sorted(Path(p).name for p in saved["plots"])
    assert names == ["r1_boxes.png", "r1_error.png", "r1_map.png", "r1_path.png"]
    for p in saved["plots"]:
        assert Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert saved["robots"]["r1"]["map"]["match_ratio"] == pytest.approx(
        exp["match_ratio"], abs=1e-6
    )
    # without --json: a digest a person reads, and where the summary is
    human = subprocess.run([*HILNAV, "analyze", str(path), "--out", str(out), "--no-plots"],
                           capture_output=True, text=True, env=hilnav_env(), timeout=120)  # fmt: skip
    assert human.returncode == 0 and not human.stdout.lstrip().startswith("{")
    assert "r1" in human.stdout and f"summary and plots: {out}/" in human.stdout


def test_digest_has_the_figures_of_the_summary(synth: tuple[Path, dict]) -> None:
    path, exp = synth
    a = analyze(path)
    s = summary_json(a)["robots"]["r1"]
    lines = digest(a)
    pose = s["paths"]["pose"]["position_error_m"]
    assert lines[0].startswith(f"  r1 pose     path error mean {pose['mean']:.3f} m")
    kinds = ["pose", "heading", "odometry", "map", "map", "heading", "CP"]
    assert [line.split()[1] for line in lines] == kinds
    assert f"match ratio {exp['match_ratio']:.3f} against the office plan" in lines[3]
    prec = s["map"]["scores"]["occupied_precision"]
    assert f"occupied precision {prec:.3f}" in lines[4] and "against the plan" in lines[4]
    assert f"NEES mean {s['heading_consistency']['mean_nees']:.2f}" in lines[5]
    frac = 100 * s["cp_boxes"]["contained_fraction"]
    assert lines[6] == f"  r1 CP boxes contain the truth {frac:.1f} % (median area 0.2 m2)"


def test_cli_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    proc = subprocess.run(
        [*HILNAV, "analyze", str(tmp_path / "nope.mcap")],
        capture_output=True,
        text=True,
        env=hilnav_env(),
        cwd=ROOT,
        timeout=60,
    )
    assert proc.returncode == 2 and "no such log file" in proc.stderr


def _rotated_run(path: Path, with_truth: bool) -> None:
    """A pose source in its own frame: the truth rotated by 30 deg and shifted."""
    import math

    from hilnav.log.writer import LogWriter
    from msgs import GpsFix, GroundTruth, Pose2D, PoseEstimate
    from tests.logsynth import T0, truth_path

    t_s, truth = truth_path()
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    with LogWriter(path, metadata={"robot": "r1"}, wall_clock=False) as w:
        for i, ts in enumerate(t_s):
            t = T0 + int(round(ts * 1e9))
            x, y, th = truth[i]
            if with_truth:
                w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(x, y, th)), t)
            elif i % 10 == 0:
                w.write("/r1/gps", GpsFix(t, mode=2, east_m=x, north_m=y), t)
            p = Pose2D(c * x - s * y + 5.0, s * x + c * y - 2.0, th)
            w.write("/r1/pose", PoseEstimate(t, p, (0.0,) * 9), t)


@pytest.mark.parametrize("with_truth", [True, False])
def test_rigid_fit_recovers_a_source_in_its_own_frame(tmp_path: Path, with_truth: bool) -> None:
    path = tmp_path / "rot.mcap"
    _rotated_run(path, with_truth)
    ra = analyze(path).robots["r1"]
    assert ra.reference == ("truth" if with_truth else "gps")
    pose = ra.paths["pose"].position
    assert pose.error_m.mean > 3.0
    assert pose.after_rigid_fit_m.max < 1e-6
    assert pose.rigid_fit.dtheta_deg == pytest.approx(-30.0, abs=1e-6)


def test_times_are_the_stamps_not_the_late_log_times(tmp_path: Path) -> None:
    """A stalled service loop logs its outputs late: errors use the messages' stamps."""
    from hilnav.log.writer import LogWriter
    from msgs import GroundTruth, Pose2D, PoseEstimate
    from tests.logsynth import T0, truth_path

    t_s, truth = truth_path()
    path = tmp_path / "late.mcap"
    with LogWriter(path, metadata={"robot": "r1"}, wall_clock=False) as w:
        for i, ts in enumerate(t_s):
            t = T0 + int(round(ts * 1e9))
            x, y, th = truth[i]
            w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(x, y, th)), t)
            late = t + (3_000_000_000 if 100 <= i < 130 else 1_000_000)
            w.write("/r1/pose", PoseEstimate(t, Pose2D(x, y, th), (0.0,) * 9), late)
    pos = analyze(path).robots["r1"].paths["pose"].position
    assert pos.error_m.max < 1e-9
    assert pos.relative_10m_m is None  # the loop is 8 m: no stretch of 10 m to score


def test_shape_and_relative_errors_ignore_the_frame_and_see_a_scale() -> None:
    """``error_after_rigid_fit`` and ``relative_error`` (hilnav.analysis.geometry): a
    track drawn in another frame (turned 40 deg, shifted) has neither; the same track 5 %
    too large has a relative error of 5 % of the 10 m stretches."""

    rng = np.random.default_rng(3)
    th = np.cumsum(rng.normal(0.0, 0.05, 400))
    steps = 0.1 * np.column_stack([np.cos(th), np.sin(th)])
    xy = np.cumsum(steps, axis=0)
    ref = np.column_stack([xy, th])
    a = np.radians(40.0)
    c, s = np.cos(a), np.sin(a)
    moved = np.column_stack([c * xy[:, 0] - s * xy[:, 1] + 3.0, s * xy[:, 0] + c * xy[:, 1] - 2.0,
                             th + a])  # fmt: skip
    assert error_after_rigid_fit(moved, ref) < 1e-9
    assert relative_error(moved, ref, 10.0) < 1e-9
    assert np.mean(np.hypot(*(moved[:, :2] - ref[:, :2]).T)) > 1.0  # far apart as they are
    large = np.column_stack([1.05 * xy, th])
    rel = relative_error(large, ref, 10.0)
    assert rel == pytest.approx(0.05 * 10.0, rel=0.05)  # stretches just over 10 m long
    assert error_after_rigid_fit(large, ref) > 0.0
    assert np.isnan(relative_error(large, ref, 1e6))


def test_relative_error_over_10_m_ignores_the_frame_and_is_reported(tmp_path: Path) -> None:
    """Two laps (16 m) of a source drawn in a frame turned by 30 deg and shifted, heading
    included: far from the truth, but its motions over 10 m are exact, and the report
    says so (``relative_error_10m_m``)."""
    from hilnav.log.writer import LogWriter
    from msgs import GroundTruth, Pose2D, PoseEstimate
    from tests.logsynth import T0, truth_path

    t_s, lap = truth_path()
    truth = np.concatenate([lap, lap])
    t_s = np.concatenate([t_s, t_s + t_s[-1] + 0.1])
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    path = tmp_path / "laps.mcap"
    with LogWriter(path, metadata={"robot": "r1"}, wall_clock=False) as w:
        for ts, (x, y, th) in zip(t_s, truth, strict=True):
            t = T0 + int(round(ts * 1e9))
            w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(x, y, th)), t)
            p = Pose2D(c * x - s * y + 5.0, s * x + c * y - 2.0, wrap_angle(th + np.radians(30.0)))
            w.write("/r1/pose", PoseEstimate(t, p, (0.0,) * 9), t)
    a = analyze(path)
    pos = a.robots["r1"].paths["pose"].position
    assert pos.error_m.mean > 3.0
    assert pos.relative_10m_m is not None and pos.relative_10m_m < 1e-9
    rep = summary_json(a)["robots"]["r1"]["paths"]["pose"]
    assert rep["relative_error_10m_m"] == pytest.approx(0.0, abs=1e-9)
