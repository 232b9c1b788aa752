"""The live view on the Foxglove WebSocket protocol, seen by a real WebSocket client: the
bridge serves exactly the log's records; `hilnav run --foxglove` serves the daemon on the
emulated robot; `hilnav view` serves every robot on the Zenoh bus."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

import msgs
from hilnav.bus import Bus, ZenohSettings, free_tcp_port
from hilnav.live import LiveBridge, LiveError
from hilnav.log.writer import LogWriter
from msgs import GpsFix, GyroSample, Interval, Pose2D, PoseBox, PoseEstimate, RobotOdometry
from tests.conftest import HILNAV, hilnav_env
from tests.foxglove_client import FoxgloveClient, Received

T0 = 1_700_000_000_000_000_000


def _messages(robot: str, t: int) -> list[tuple[str, object]]:
    box = PoseBox(t, robot, Interval(0.0, 0.4), Interval(-0.1, 0.2), Interval(0.0, 0.2))
    return [
        (
            f"/{robot}/odometry",
            RobotOdometry(t, Pose2D(0.3, 0, 0.1), 0.3, 0.3, 0.3, 0, 12, True, True),
        ),
        (f"/{robot}/pose", PoseEstimate(t, Pose2D(0.5, 0.1, 0.2), (0.01,) * 9)),
        (f"/{robot}/gyro", GyroSample(t, 0.01, 0.2)),
        (f"/{robot}/gps", GpsFix(t, lat_deg=37.5, lon_deg=127.0, std_lat_m=2.0, std_lon_m=3.0)),
        (f"/{robot}/pose_box", box),
    ]


def _mcap(path: Path) -> tuple[dict[str, tuple[str, bytes]], set[tuple[str, str, bytes]]]:
    """topic -> (schema name, schema data), and every (topic, schema, payload) of a log."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        schemas = {
            c.topic: (summary.schemas[c.schema_id].name, summary.schemas[c.schema_id].data)
            for c in summary.channels.values()
        }
        records = {(c.topic, s.name, m.data) for s, c, m in reader.iter_messages()}
    return schemas, records


def test_the_bridge_serves_exactly_the_channels_and_bytes_the_log_gets(tmp_path: Path) -> None:
    path = tmp_path / "same.mcap"
    batch = _messages("r1", T0)
    with LogWriter(path, wall_clock=False) as w:
        for topic, msg in batch:
            w.write(topic, msg, T0)
    schemas, records = _mcap(path)
    assert {"/r1/pose", "/r1/fox/pose", "/tf", "/r1/fox/gps", "/r1/fox/pose_box"} <= set(schemas)

    def write_batch() -> None:  # until the client's subscriptions reached the server
        for topic, msg in batch:
            bridge.write(topic, msg, T0)

    with LiveBridge(port=0) as bridge, FoxgloveClient(bridge.url) as client:
        write_batch()
        got = client.collect(
            wanted=lambda topic: True,
            done=lambda rs: {r.topic for r in rs} == set(schemas),
            step=write_batch,
        )
    assert client.server_info["op"] == "serverInfo"
    assert client.ws.subprotocol == "foxglove.sdk.v1"
    advertised = {c["topic"]: c for c in client.channels.values()}
    assert set(advertised) == set(schemas)
    for topic, (name, data) in schemas.items():
        ch = advertised[topic]
        assert (ch["schemaName"], ch["encoding"], ch["schemaEncoding"]) == (
            name,
            "json",
            "jsonschema",
        )
        assert ch["schema"].encode() == data  # the same JSON Schema bytes
    assert {(r.topic, r.schema_name, r.data) for r in got} == records
    assert all(r.log_time_ns == T0 for r in got)


def test_a_taken_port_is_a_clear_error() -> None:
    with LiveBridge(port=0) as first, pytest.raises(LiveError, match="cannot serve"):
        LiveBridge(port=first.port)


def _pose_of(r: Received) -> tuple[float, float]:
    p = msgs.decode(PoseEstimate, r.data).pose
    return p.x, p.y


def test_hilnav_run_foxglove_serves_the_daemon_live(tmp_path: Path) -> None:
    zport, wport = free_tcp_port(), free_tcp_port()
    cfg = tmp_path / "r1.toml"
    cfg.write_text(
        f'name = "r1"\n[zenoh]\nlisten = ["tcp/127.0.0.1:{zport}"]\n[log]\ndir = "{tmp_path}"\n'
        "[services.mapping]\nenabled = false\n[simulation]\nseed = 5\n"
    )
    log = tmp_path / "run.mcap"
    cmd = [*HILNAV, "run", "--config", str(cfg), "--log", str(log), "--quiet"]
    proc = subprocess.Popen(
        [*cmd, "--foxglove", str(wport)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=hilnav_env(),
    )
    wanted = {"/r1/pose", "/r1/fox/pose", "/r1/odometry", "/tf", "/r1/status"}
    try:
        with FoxgloveClient(f"ws://127.0.0.1:{wport}") as client:
            got = client.collect(
                wanted=lambda topic: topic in wanted,
                done=lambda rs: {r.topic for r in rs} == wanted,
            )
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert f"live view on ws://127.0.0.1:{wport}" in out
    poses = [r for r in got if r.topic == "/r1/pose"]
    x, y = _pose_of(poses[-1])
    assert math.hypot(x - 1.5, y - 1.5) < 0.2  # the office's start pose
    view = next(r for r in got if r.topic == "/r1/fox/pose")
    assert view.schema_name.startswith("foxglove.") and "pose" in view.json()
    assert msgs.decode(msgs.DaemonStatus, next(r for r in got if r.topic == "/r1/status").data)
    # the channels served are the log's channels, schemas included
    schemas, records = _mcap(log)
    for ch in client.channels.values():
        assert schemas[ch["topic"]] == (ch["schemaName"], ch["schema"].encode()), ch["topic"]
    logged = {(t, d) for t, _, d in records}
    assert all((r.topic, r.data) in logged for r in got if r.topic == "/r1/pose")


@pytest.fixture
def viewer():
    zport, wport = free_tcp_port(), free_tcp_port()
    proc = subprocess.Popen(
        [*HILNAV, "view", "--listen", f"tcp/127.0.0.1:{zport}", "--port", str(wport)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=hilnav_env(),
    )
    yield proc, zport, wport
    if proc.poll() is None:
        proc.kill()
        proc.wait(10)


def test_hilnav_view_serves_every_robot_on_the_bus(viewer) -> None:
    proc, zport, wport = viewer
    robots = {name: Bus(name, ZenohSettings.loopback(connect_ports=[zport])) for name in "ab"}

    def publish() -> None:
        t = time.time_ns()
        for name, bus in robots.items():
            x = 1.0 if name == "a" else 2.0
            bus.publish("pose", PoseEstimate(t, Pose2D(x, 0, 0), (0.0,) * 9))
            bus.publish("odometry", RobotOdometry(t, Pose2D(), 0, 0, 0, 0, 12, False, True))

    wanted = {"/a/pose", "/b/pose", "/a/fox/pose", "/b/fox/pose", "/tf"}

    def done(rs) -> bool:
        # every topic, and a robot's base_link among the transforms (the /tf frames of
        # one publish come as several messages, in no fixed order)
        return {r.topic for r in rs} == wanted and any(
            r.json()["child_frame_id"].endswith("base_link") for r in rs if r.topic == "/tf"
        )

    try:
        with FoxgloveClient(f"ws://127.0.0.1:{wport}") as client:
            got = client.collect(wanted=lambda topic: topic in wanted, done=done, step=publish)
    finally:
        for bus in robots.values():
            bus.close()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert f"ws://127.0.0.1:{wport}" in out
    names = {c["topic"]: c["schemaName"] for c in client.channels.values()}
    assert names["/a/pose"] == "hilnav.PoseEstimate" and names["/b/fox/pose"] == (
        "foxglove.PoseInFrame"
    )
    assert _pose_of(next(r for r in got if r.topic == "/b/pose")) == (2.0, 0.0)
    children = {r.json()["child_frame_id"] for r in got if r.topic == "/tf"}
    assert any(c.endswith("base_link") for c in children)
    assert json.loads(next(r for r in got if r.topic == "/a/pose").data)["stamp_ns"] > T0
