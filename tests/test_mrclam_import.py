"""hilnav import mrclam: the real MRCLAM run into a multi-robot log that replay and analyze
read, checked against the data set's files; and broken or odd run directories."""

from __future__ import annotations

import json
import subprocess
from collections import Counter
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from hilnav.importers.mrclam import import_mrclam
from hilnav.log.foxglove_schemas import official_schema
from hilnav.log.reader import ReadStats, read_messages, read_metadata
from msgs import GroundTruth, LandmarkMap, RangeBearing, VelocityOdometry
from tests.conftest import HILNAV, ROOT, SHARED, hilnav_env, require

DATA = SHARED / "data/mrclam/MRCLAM_Dataset6"
# 30 s of robots 1 and 4 that hold a gap of the motion capture for both (at 540.4 s)
START_S, SECONDS, ROBOTS = 530.0, 30.0, (1, 4)


def _cli(*args: str, timeout: int = 240) -> dict:
    proc = subprocess.run(
        [*HILNAV, *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT,
        timeout=timeout,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def sliced(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    require(DATA)
    out = tmp_path_factory.mktemp("mrclam") / "slice.mcap"
    robots = ",".join(str(n) for n in ROBOTS)
    report = _cli("import", "mrclam", str(DATA), str(out), "--start", str(START_S),
                  "--seconds", str(SECONDS), "--robots", robots)  # fmt: skip
    return out, report


def _expected() -> tuple[dict[str, Counter], dict[str, int]]:
    """Per robot and topic, the rows of the files inside the slice (in ms, as the files
    hold them), and the truth samples inside it that follow a gap of more than 0.25 s."""
    from localization.mrclam import load_mrclam

    run = load_mrclam(DATA, list(ROBOTS))
    lo = round(run.start_s * 1000) + round(START_S * 1000)
    hi = lo + round(SECONDS * 1000)
    counts: dict[str, Counter] = {}
    gaps: dict[str, int] = {}
    for n, rr in run.robots.items():
        c = counts.setdefault(f"r{n}", Counter())

        def inside(t: np.ndarray) -> np.ndarray:
            ms = np.round(t * 1000).astype(np.int64)
            return (ms >= lo) & (ms <= hi)

        c["velocity"] = int(inside(rr.odometry[:, 0]).sum())
        c["truth"] = int(inside(rr.truth[:, 0]).sum())
        m = rr.measurements[inside(rr.measurements[:, 0])]
        c["landmark_range_bearing"] = int(np.isin(m[:, 1], list(run.landmarks)).sum())
        c["peer_range_bearing"] = int((m[:, 1] <= 5).sum())
        c["landmark_map"] = 1
        ms = np.round(rr.truth[:, 0] * 1000).astype(np.int64)
        after = np.concatenate([[False], np.diff(ms) > 250])
        gaps[f"r{n}"] = int((after & (ms >= lo) & (ms <= hi)).sum())
    return counts, gaps


def test_the_slice_reads_back_with_the_counts_of_the_files(sliced) -> None:
    out, report = sliced
    counts, gaps = _expected()
    assert report["robots"] == ["r1", "r4"]
    assert report["per_robot"] == {r: dict(sorted(c.items())) for r, c in counts.items()}
    assert {r: g["count"] for r, g in report["truth_gaps"].items()} == gaps
    assert all(g >= 1 for g in gaps.values())  # the slice was chosen to hold a gap

    stats = ReadStats()
    got = list(read_messages(out, stats=stats))
    assert stats.unknown == 0 and stats.malformed == 0
    seen = {r: Counter() for r in counts}
    for m in got:
        robot, kind = m.topic.strip("/").split("/", 1)
        seen[robot][kind] += 1
        assert m.log_time_ns == m.publish_time_ns == m.msg.stamp_ns
    assert seen == counts
    times = [m.log_time_ns for m in got]
    assert times == sorted(times)
    assert got[0].topic.endswith("/landmark_map")  # the map comes first

    by = {(m.topic, type(m.msg)) for m in got}
    for robot in counts:
        assert (f"/{robot}/velocity", VelocityOdometry) in by
        assert (f"/{robot}/truth", GroundTruth) in by
        assert (f"/{robot}/landmark_range_bearing", RangeBearing) in by
    flagged = Counter(m.topic for m in got if isinstance(m.msg, GroundTruth) and m.msg.gap_before_s)
    assert flagged == Counter({f"/{r}/truth": g for r, g in gaps.items()})
    for m in got:
        if isinstance(m.msg, GroundTruth) and m.msg.gap_before_s:
            assert m.msg.gap_before_s > 0.25
    lms = [m.msg for m in got if isinstance(m.msg, RangeBearing) and m.msg.landmark]
    assert all(m.target == f"l{m.subject}" and 6 <= m.subject <= 20 for m in lms)
    peers = [m.msg for m in got if isinstance(m.msg, RangeBearing) and not m.msg.landmark]
    assert peers and all(m.target == f"r{m.subject}" != m.robot for m in peers)
    lmap = next(m.msg for m in got if isinstance(m.msg, LandmarkMap))
    rows = np.loadtxt(DATA / "Landmark_Groundtruth.dat", comments="#")
    assert list(lmap.ids) == rows[:, 0].astype(int).tolist()
    assert np.allclose(lmap.xs, rows[:, 1]) and np.allclose(lmap.cov_yy, rows[:, 4] ** 2)
    # one velocity row, exactly as in the file
    odo = np.loadtxt(DATA / "Robot4_Odometry.dat", comments="#")
    v = next(m.msg for m in got if m.topic == "/r4/velocity")
    row = odo[np.argmin(np.abs(odo[:, 0] - v.stamp_ns * 1e-9))]
    assert (v.linear_mps, v.angular_radps, v.commanded) == (row[1], row[2], True)

    meta = read_metadata(out)["hilnav"]
    assert meta["dataset"] == "mrclam" and meta["robots"] == "r1,r4"
    assert len(meta["initial_pose.r1"].split(",")) == 3


def test_the_official_mcap_reader_opens_it_and_the_views_are_foxglove_schemas(sliced) -> None:
    out, report = sliced
    kinds: Counter = Counter()
    validators: dict[int, jsonschema.protocols.Validator] = {}
    n = 0
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            n += 1
            if schema.id not in validators:
                doc = json.loads(schema.data)
                if schema.name.startswith("foxglove."):
                    assert doc == official_schema(schema.name)
                assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
                validators[schema.id] = jsonschema.validators.validator_for(doc)(doc)
            errors = [
                e.message for e in validators[schema.id].iter_errors(json.loads(message.data))
            ]
            assert not errors, (channel.topic, errors[:3])
            if schema.name.startswith("foxglove."):
                kinds[schema.name] += 1
    assert n == summary.statistics.message_count
    truth = sum(c["truth"] for c in report["per_robot"].values())
    assert kinds == {"foxglove.PoseInFrame": truth, "foxglove.SceneUpdate": 2}


def test_replay_dead_reckons_every_robot_and_analyze_scores_each_outside_the_gaps(
    sliced, tmp_path: Path
) -> None:
    src, report = sliced
    reps = [_cli("replay", str(src), "--out", str(tmp_path / n)) for n in ("a.mcap", "b.mcap")]
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()
    rep = reps[0]
    assert rep["robot"] == "r1,r4" and rep["pipeline_errors"] == 0
    assert rep["fed"] == {k: v for k, v in report["messages"].items() if k != "truth"}
    assert rep["outputs"]["dead_reckoning"] == report["messages"]["velocity"]
    # the CP's boxes every 0.1 s; 1 and 4 do not meet: no sightings, no fixes
    assert sorted(rep["outputs"]) == ["dead_reckoning", "pose", "pose_box"]
    _the_replayed_ekf_is_the_batch_ekf(tmp_path / "a.mcap", DATA, START_S, SECONDS, ROBOTS)

    summary = _cli("analyze", str(tmp_path / "a.mcap"), "--out", str(tmp_path / "an"),
                   "--no-plots", "--json")  # fmt: skip
    for robot in ("r1", "r4"):
        ra = summary["robots"][robot]
        assert ra["reference"] == "truth" and ra["landmarks"]["count"] == 15
        assert ra["truth_gaps"]["count"] == report["truth_gaps"][robot]["count"]
        dr = ra["paths"]["dead_reckoning"]
        n = ra["topics"]["dead_reckoning"]
        assert n == report["per_robot"][robot]["velocity"]
        assert 0.9 * n < dr["samples"] < n  # the instants inside the gap are not scored
        assert dr["aligned_at_start"] and np.isfinite(dr["position_error_m"]["rms"])
        # the MRCLAM EKF's pose, scored against the truth outside its gaps
        ekf = ra["paths"]["pose"]
        assert ekf["position_error_m"]["rms"] < 0.2, (robot, ekf["position_error_m"])
        assert ra["ekf_3sigma"]["pose"]["contained_fraction"] >= 0.95
        assert ra["ekf_3sigma"]["pose"]["poses"] < ra["topics"]["pose"]  # the gap
    # analyze on the imported log alone: the truth, its gaps and the map, per robot
    summary = _cli("analyze", str(src), "--out", str(tmp_path / "an0"), "--no-plots", "--json")
    assert sorted(summary["robots"]) == ["r1", "r4"]
    for ra in summary["robots"].values():
        assert ra["reference_distance_m"] > 0 and ra["truth_gaps"]["count"] >= 1


def _the_replayed_ekf_is_the_batch_ekf(
    replayed: Path, data: Path, start_s: float, seconds: float, robots: tuple[int, ...]
) -> dict:
    """The replay's ``pose`` messages (the EKF service, message by message, the robots
    exchanging estimates and position fixes) are the batch runner's split-CI track on
    the same rows of the files; the batch's tracks."""
    from localization.mrclam import MrclamRun, RobotRun, load_mrclam
    from localization.mrclam_ekf import MrclamEkfConfig, run_ekf

    run = load_mrclam(data, list(robots))
    lo = round(run.start_s * 1000) + round(start_s * 1000)

    def cut(a: np.ndarray) -> np.ndarray:
        ms = np.round(a[:, 0] * 1000).astype(np.int64)
        return a[(ms >= lo) & (ms <= lo + round(seconds * 1000))]

    robots = {
        n: RobotRun(n, cut(r.odometry), cut(r.measurements), r.truth) for n, r in run.robots.items()
    }
    sliced = MrclamRun(run.directory, robots, run.landmarks, run.barcodes)
    tracks = run_ekf(sliced, config=MrclamEkfConfig(cooperation="split_ci"))
    poses: dict[str, list] = {}
    for m in read_messages(replayed):
        if m.topic.endswith("/pose"):
            poses.setdefault(m.topic.split("/")[1], []).append(m.msg)
    for n, tr in tracks.items():
        got = poses[f"r{n}"]
        grid = tr.on_grid
        assert len(got) == int(grid.sum())
        np.testing.assert_allclose([p.stamp_ns * 1e-9 for p in got], tr.t[grid], atol=1e-6)
        np.testing.assert_allclose([(p.pose.x, p.pose.y) for p in got], tr.mean[grid, :2],
                                   atol=1e-6)  # fmt: skip
        cov = np.array([p.covariance for p in got]).reshape(-1, 3, 3)
        # (the split-CI weight is a grid search: 1e-7 s apart, it may land a step away)
        np.testing.assert_allclose(cov, tr.cov[grid], rtol=1e-3, atol=1e-9)
    return tracks


def test_the_ekf_replay_of_robots_that_meet_is_the_batch_ekf_and_analyze_scores_it(
    tmp_path: Path,
) -> None:
    """40 s of robots 2, 3 and 5, which see one another: the replayed EKF services
    exchange estimates and position fixes and give the batch's split-CI tracks; analyze
    scores their pose (RMSE, 3-sigma containment) against the truth."""
    require(DATA)
    from hilnav.analysis.analyze import analyze
    from hilnav.replay.replayer import replay

    src, dst = tmp_path / "coop.mcap", tmp_path / "coop_replay.mcap"
    import_mrclam(DATA, src, seconds=40.0, start_s=60.0, robots=[2, 3, 5])
    rep = replay(src, dst, progress=False)
    assert rep.pipeline_errors == 0 and rep.outputs["peer_fix"] > 20
    tracks = _the_replayed_ekf_is_the_batch_ekf(dst, DATA, 60.0, 40.0, (2, 3, 5))
    seen = sum(t.counts["seen_accepted"] + t.counts["seen_no_gain"] for t in tracks.values())
    assert seen == rep.outputs["peer_fix"]  # every fix reached its robot
    assert sum(t.counts["robot_accepted"] + t.counts["seen_accepted"] for t in tracks.values())
    result = analyze(dst)
    for robot in ("r2", "r3", "r5"):
        ra = result.robots[robot]
        assert ra.ekf_3sigma["pose"].contained_fraction >= 0.95
        assert ra.ekf_3sigma["pose"].poses >= 790  # 40 s every 0.05 s (no truth gap)
        err = ra.series.errors["pose"].pos_err
        assert np.sqrt(np.mean(err**2)) < 0.12


def _run_dir(tmp_path: Path) -> Path:
    """A small run: robots 1, 2 (and 3's barcode, no files), landmark 6; a truth gap."""
    d = tmp_path / "run"
    d.mkdir()
    (d / "Barcodes.dat").write_text("# subject barcode\n1 5\n2 14\n3 41\n6 27\n7 54\n")
    (d / "Landmark_Groundtruth.dat").write_text("6 1.0 2.0 0.01 0.02\n")
    for n in (1, 2):
        (d / f"Robot{n}_Odometry.dat").write_text("10.0 0.1 0.0\n10.5 0.1 0.2\n11.0 0.0 0.0\n")
        (d / f"Robot{n}_Groundtruth.dat").write_text(
            "9.0 0 0 0\n10.0 0 0 0\n10.1 0.01 0 0\n10.9 0.09 0 0.1\n11.0 0.1 0 0.1\n"
        )
    # robot 1 sees: landmark 6, robot 2, robot 3 (no files), itself, landmark 7 (no row)
    (d / "Robot1_Measurement.dat").write_text(
        "10.2 27 2.0 0.1\n10.3 14 1.5 -0.2\n10.4 41 3.0 0.0\n10.5 5 1.0 0.0\n10.6 54 1.0 0\n"
    )
    (d / "Robot2_Measurement.dat").write_text("# robot 2 sees landmark 6\n10.7 27 2.5 0.0\n")
    return d


def test_a_small_run_names_targets_flags_gaps_and_counts_what_it_drops(tmp_path: Path) -> None:
    out = tmp_path / "o.mcap"
    rep = import_mrclam(_run_dir(tmp_path), out).as_dict()
    assert rep["per_robot"]["r1"] == {
        "landmark_map": 1, "landmark_range_bearing": 1, "peer_range_bearing": 1,
        "truth": 4, "velocity": 3,
    }  # fmt: skip
    # robot 3 has a barcode but no files: neither a landmark nor a robot of the run
    assert rep["dropped"] == {"r1_self_measurement": 1, "r1_unknown_subject": 2}
    # gaps are judged against the file's previous sample, also one before the log starts
    assert rep["truth_gaps"]["r1"] == {"count": 2, "total_s": 1.8, "longest_s": 1.0}
    msgs = list(read_messages(out))
    assert msgs[0].log_time_ns == 10_000_000_000  # the run starts at the first odometry
    truth = [m.msg for m in msgs if m.topic == "/r1/truth"]
    assert [round(t.gap_before_s, 6) for t in truth] == [1.0, 0.0, 0.8, 0.0]
    rb = [m.msg for m in msgs if isinstance(m.msg, RangeBearing)]
    assert [(m.robot, m.target, m.landmark, m.subject) for m in rb] == [
        ("r1", "l6", True, 6), ("r1", "r2", False, 2), ("r2", "l6", True, 6),
    ]  # fmt: skip
    meta = read_metadata(out)["hilnav"]
    assert meta["initial_pose.r2"] == "0.0,0.0,0.0"


def test_bad_arguments_and_a_missing_directory_are_clear_errors(tmp_path: Path) -> None:
    for args in (
        [str(tmp_path / "nothing"), str(tmp_path / "o.mcap")],
        [str(_run_dir(tmp_path)), str(tmp_path / "o.mcap"), "--robots", "one"],
        [str(tmp_path / "run"), str(tmp_path / "o.mcap"), "--robots", "1,9"],
        [str(tmp_path / "run"), str(tmp_path / "o.mcap"), "--seconds", "0"],
    ):
        proc = subprocess.run(
            [*HILNAV, "import", "mrclam", *args],
            capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=60,
        )  # fmt: skip
        assert proc.returncode == 2, (args, proc.stderr)
        assert "Traceback" not in proc.stderr and proc.stderr.strip()
