"""LogWriter: real MCAP files read back by the mcap library; Foxglove views; crash safety."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import jsonschema
import pytest
from mcap.reader import make_reader

import msgs
from hilnav.log import foxglove
from hilnav.log.foxglove_schemas import SCHEMAS
from hilnav.log.reader import ReadStats, ScanResult, read_messages, read_metadata, scan_records
from hilnav.log.recover import recover
from hilnav.log.writer import LogWriter
from msgs import (
    GpsFix,
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    Interval,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RawBytes,
    RobotOdometry,
)
from tests.conftest import ROOT, hilnav_env

T0 = 1_700_000_000_000_000_000


def _odo(t: int, x: float) -> RobotOdometry:
    return RobotOdometry(t, Pose2D(x, 0.0, 0.1), 0.3, 0.3, 0.3, 0.0, 12.5, True, True)


def _write_sample(path: Path, n: int = 50, **kw) -> None:
    with LogWriter(path, metadata={"robot": "r1", "plan": "office", "seed": "3"}, **kw) as w:
        for i in range(n):
            t = T0 + i * 100_000_000
            w.write("/r1/odometry", _odo(t, 0.03 * i), t, t - 5)
            w.write("/r1/gyro", GyroSample(t, 0.01, 0.001 * i), t)
            w.write("/r1/pose", PoseEstimate(t, Pose2D(0.03 * i, 0.01, 0.1), (0.01,) * 9), t)
            w.write("/r1/heading", HeadingEstimate(t, 0.1, 1e-4, Pose2D(0.03 * i, 0, 0.1)), t)
            box = PoseBox(t, "r1", Interval(0.0, 0.4), Interval(-0.1, 0.2), Interval(0.0, 0.2))
            w.write("/r1/pose_box", box, t)
            w.write(
                "/r1/gps", GpsFix(t, lat_deg=37.5, lon_deg=127.0, std_lat_m=2.0, std_lon_m=3.0), t
            )
            w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(0.03 * i, 0.0, 0.1)), t)
            w.write("/r1/raw/arcos", RawBytes(t, "arcos", bytes([0xFA, 0xFB, i % 256])), t)


def test_mcap_library_reads_topics_schemas_times(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    _write_sample(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        chans = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        counts = summary.statistics.channel_message_counts
        by_topic = {c.topic: counts[c.id] for c in summary.channels.values()}
        msgs_seen = list(reader.iter_messages(topics=["/r1/odometry"]))
        meta = list(reader.iter_metadata())
    assert chans["/r1/odometry"].name == "hilnav.RobotOdometry"
    assert chans["/r1/odometry"].encoding == "jsonschema"
    assert json.loads(chans["/r1/odometry"].data) == msgs.json_schema(RobotOdometry)
    assert chans["/r1/pose"].name == "hilnav.PoseEstimate"
    assert chans["/r1/fox/pose"].name == "foxglove.PoseInFrame"
    assert chans["/r1/fox/gps"].name == "foxglove.LocationFix"
    assert chans["/r1/fox/pose_box"].name == "foxglove.SceneUpdate"
    assert chans["/tf"].name == "foxglove.FrameTransform"
    assert by_topic["/r1/odometry"] == 50 and by_topic["/tf"] == 100  # odom->base + map->odom
    _, ch, m = msgs_seen[3]
    assert ch.message_encoding == "json"
    assert m.log_time == T0 + 3 * 100_000_000 and m.publish_time == m.log_time - 5
    assert m.sequence == 3
    assert msgs.decode(RobotOdometry, m.data) == _odo(m.log_time, 0.03 * 3)
    assert meta[0].name == "hilnav" and meta[0].metadata["plan"] == "office"


def test_read_messages_round_trip_and_counts(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    _write_sample(path, n=20)
    stats = ReadStats()
    got = list(read_messages(path, stats=stats))
    assert stats.decoded == 20 * 8 and stats.views == 20 * 7 and stats.unknown == 0
    raw = [m.msg for m in got if m.topic == "/r1/raw/arcos"]
    assert raw[5] == RawBytes(T0 + 5 * 100_000_000, "arcos", bytes([0xFA, 0xFB, 5]))
    times = [m.log_time_ns for m in got]
    assert times == sorted(times)
    assert read_metadata(path)["hilnav"]["seed"] == "3"
    only = list(read_messages(path, topics=["/r1/pose"]))
    assert len(only) == 20 and all(isinstance(m.msg, PoseEstimate) for m in only)


def test_unknown_and_malformed_records_are_counted_not_raised(tmp_path: Path) -> None:
    path = tmp_path / "b.mcap"
    with LogWriter(path) as w:
        w.write("/r1/gyro", GyroSample(T0, 0.1, 0.2), T0)
        w.write_encoded("/r1/other", "acme.Thing", {"type": "object"}, b'{"a":1}', T0 + 1)
        w.write_encoded("/r1/gyro", "hilnav.GyroSample", None, b'{"stamp_ns":"x"}', T0 + 2)
        w.write_encoded("/r1/gyro", "hilnav.GyroSample", None, b"not json", T0 + 3)
    stats = ReadStats()
    got = list(read_messages(path, stats=stats))
    assert [m.msg for m in got] == [GyroSample(T0, 0.1, 0.2)]
    assert stats.unknown == 1 and stats.unknown_schemas["acme.Thing"] == 1
    assert stats.malformed == 2 and len(stats.errors) == 2


def test_views_validate_against_their_foxglove_schemas() -> None:
    state = foxglove.ViewState()
    t = T0 + 123
    inputs = [
        ("/r1/odometry", _odo(t, 1.0)),
        ("/r1/pose", PoseEstimate(t, Pose2D(1.0, 2.0, 3.0), (0.0,) * 9)),
        ("/r1/gps", GpsFix(t, lat_deg=-33.9, lon_deg=151.2, hdop=1.2)),
        ("/r1/pose_box", PoseBox(t, "r1", Interval(0, 1), Interval(2, 3), Interval(-1, 1))),
        ("/r1/pose_box", PoseBox(t, "r1", Interval(1, 0), Interval(2, 3), Interval(-1, 1))),
        ("/r1/truth", GroundTruth(t, "r1", Pose2D(1, 2, 3))),
    ]
    seen = set()
    for topic, m in inputs:
        for _vtopic, schema, body in foxglove.views(topic, m, state):
            jsonschema.validate(body, SCHEMAS[schema])
            json.dumps(body, allow_nan=False)
            assert body.get("timestamp", {"sec": 1}) != {"sec": 0, "nsec": 0}
            seen.add(schema)
    assert seen == set(SCHEMAS)
    assert foxglove.views("/r1/gps", GpsFix(t), state) == []  # no fix: no LocationFix


def test_map_to_odom_transform_composes_to_the_pose() -> None:
    state = foxglove.ViewState()
    t = T0
    odo = RobotOdometry(t, Pose2D(1.0, 0.5, 0.4), 0, 0, 0, 0, 12, False, True)
    foxglove.views("/r1/odometry", odo, state)
    est = Pose2D(3.0, -1.0, 1.2)
    tf = [
        b
        for _, s, b in foxglove.views("/r1/pose", PoseEstimate(t, est, (0.0,) * 9), state)
        if s == "foxglove.FrameTransform"
    ][0]
    map_odom = Pose2D(
        tf["translation"]["x"],
        tf["translation"]["y"],
        2 * math.atan2(tf["rotation"]["z"], tf["rotation"]["w"]),
    )
    back = foxglove.compose(map_odom, odo.pose)
    assert back.x == pytest.approx(est.x) and back.y == pytest.approx(est.y)
    assert math.remainder(back.theta - est.theta, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    assert tf["parent_frame_id"] == "map" and tf["child_frame_id"] == "r1/odom"


def test_gps_covariance_is_enu_diagonal() -> None:
    fix = foxglove.location_fix(GpsFix(T0, lat_deg=1.0, lon_deg=2.0, std_lat_m=2.0, std_lon_m=3.0))
    assert fix is not None
    assert fix["position_covariance_type"] == 2
    assert fix["position_covariance"][0] == 9.0 and fix["position_covariance"][4] == 4.0


def test_concurrent_writers_lose_nothing(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    n, k = 4, 500
    with LogWriter(path, flush_every_s=0.05) as w:

        def work(j: int) -> None:
            for i in range(k):
                t = T0 + i * 1_000_000 + j
                w.write(f"/r{j}/gyro", GyroSample(t, float(j), float(i)), t)

        threads = [threading.Thread(target=work, args=(j,)) for j in range(n)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    got = list(read_messages(path))
    assert len(got) == n * k
    for j in range(n):
        mine = [m.msg.angle_rad for m in got if m.topic == f"/r{j}/gyro"]
        assert mine == [float(i) for i in range(k)]


def test_same_input_same_bytes_without_wall_clock(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    _write_sample(a, n=30, wall_clock=False, flush_every_s=0.5)
    _write_sample(b, n=30, wall_clock=False, flush_every_s=0.5)
    assert a.read_bytes() == b.read_bytes()


def test_log_time_flushes_chunks_every_second(tmp_path: Path) -> None:
    path = tmp_path / "d.mcap"
    with LogWriter(path, wall_clock=False, flush_every_s=1.0) as w:
        for i in range(100):  # 10 s of log time at 10 Hz
            t = T0 + i * 100_000_000
            w.write("/r1/gyro", GyroSample(t, 0.0, 0.0), t)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    spans = [(c.message_end_time - c.message_start_time) for c in summary.chunk_indexes]
    assert len(spans) == 10 and max(spans) < 1_000_000_000


def test_rejects_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="compression"):
        LogWriter(tmp_path / "x.mcap", compression="gzip")
    w = LogWriter(tmp_path / "y.mcap")
    w.close()
    w.close()  # idempotent
    with pytest.raises(ValueError, match="closed"):
        w.write("/r1/gyro", GyroSample(T0, 0, 0), T0)


def test_times_outside_uint64_are_refused_and_the_log_stays_whole(tmp_path: Path) -> None:
    path = tmp_path / "z.mcap"
    w = LogWriter(path)
    w.write("/r1/gyro", GyroSample(T0, 0, 0), T0)
    for log_ns, pub_ns in ((T0, 2**64), (-1, None), (2**64 + 5, T0)):
        with pytest.raises(ValueError, match="uint64"):
            w.write("/r1/gyro", GyroSample(T0, 0, 0), log_ns, pub_ns)
    w.write("/r1/gyro", GyroSample(T0 + 1, 0, 0), T0 + 1)
    w.close()
    assert [m.log_time_ns for m in read_messages(path)] == [T0, T0 + 1]


CRASH_WRITER = """
import sys, time
from hilnav.log.writer import LogWriter
from msgs import GyroSample
w = LogWriter(sys.argv[1], metadata={"robot": "r1"}, flush_every_s=1.0)
print("ready", flush=True)
i = 0
while True:
    t = time.time_ns()
    w.write("/r1/gyro", GyroSample(t, 0.0, float(i)), t)
    i += 1
    time.sleep(0.002)
"""


def test_sigkilled_writer_loses_at_most_about_a_second(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-c", CRASH_WRITER, str(path)],
        stdout=subprocess.PIPE,
        env=hilnav_env(),
        cwd=ROOT,
        text=True,
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        time.sleep(2.6)
        killed_ns = time.time_ns()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.stdout is not None
    proc.stdout.close()
    # The killed file has no footer or summary ...
    scan = ScanResult()
    assert any(True for _ in scan_records(path, scan)) and not scan.complete
    out = tmp_path / "recovered.mcap"
    rep = recover(path, out)
    assert not rep.input_complete and rep.messages > 100
    # ... the recovered one is, read back by the mcap library, summary and all.
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        got = [msgs.decode(GyroSample, m.data) for _, _, m in reader.iter_messages()]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert summary is not None and summary.statistics.message_count == rep.messages
    assert meta["hilnav"]["robot"] == "r1"
    assert [g.angle_rad for g in got] == [float(i) for i in range(len(got))]  # a prefix, no gaps
    lost_s = (killed_ns - got[-1].stamp_ns) / 1e9
    assert 0.0 <= lost_s < 1.3, f"lost {lost_s:.2f} s of messages"


def test_landmark_map_view_is_a_scene_of_spheres() -> None:
    from msgs.landmarks import LandmarkMap

    lm = LandmarkMap(T0, (1, 2), (1.0, -3.0), (2.0, 4.0), (0.04, 1.0), (0.0, 0.0), (0.01, 1.0))
    ((topic, schema, body),) = foxglove.views("/vp/landmarks", lm, foxglove.ViewState())
    jsonschema.validate(body, SCHEMAS[schema])
    assert topic == "/vp/fox/landmarks" and schema == "foxglove.SceneUpdate"
    spheres = body["entities"][0]["spheres"]
    assert [(s["pose"]["position"]["x"], s["pose"]["position"]["y"]) for s in spheres] == [
        (1.0, 2.0),
        (-3.0, 4.0),
    ]
    assert spheres[0]["size"]["x"] == pytest.approx(6 * 0.2)  # 3 sigma each side
    assert spheres[1]["size"]["x"] == pytest.approx(6 * 1.0)


def test_non_finite_values_keep_the_native_record_and_skip_the_view(tmp_path: Path) -> None:
    path = tmp_path / "nan.mcap"
    with LogWriter(path) as w:
        bad = PoseEstimate(T0, Pose2D(float("nan"), 0.0, 0.0), (float("inf"),) * 9)
        w.write("/r1/pose", bad, T0)
        w.write("/r1/pose", PoseEstimate(T0 + 1, Pose2D(1.0, 0.0, 0.0), (0.0,) * 9), T0 + 1)
        assert w.views_skipped == 1
    stats = ReadStats()
    got = [m.msg for m in read_messages(path, stats=stats)]
    assert len(got) == 2 and math.isnan(got[0].pose.x) and got[0].covariance[0] == math.inf
    assert stats.views == 1
