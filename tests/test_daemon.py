"""The daemon end to end: `hilnav run` on the emulated devices (real ptys, IR over CAN
through the emulated slcan adapter), seen and driven from a second Zenoh session, logged
to an MCAP read back with the mcap library, stopped with SIGTERM."""

from __future__ import annotations

import math
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from hilnav.bus import Bus, ZenohSettings, free_tcp_port, key
from msgs import PoseEstimate, VelocityCommand
from tests.conftest import HILNAV, hilnav_env


def _wait(cond, timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return bool(cond())


class Seen:
    """What the operator's session received, by topic (thread-safe enough for tests)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.msgs: dict[str, list] = {}
        self.alive: list[tuple[str, bool]] = []

    def add(self, topic: str, msg) -> None:
        with self.lock:
            self.msgs.setdefault(topic, []).append(msg)

    def get(self, topic: str) -> list:
        with self.lock:
            return list(self.msgs.get(topic, []))


@pytest.fixture(scope="module")
def running(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("daemon")
    port = free_tcp_port()
    cfg = tmp / "r1.toml"
    cfg.write_text(
        'name = "r1"\nfleet = ["operator"]\n'
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{port}"]\n'
        f'[log]\ndir = "{tmp}"\n'
        "[cmd_vel]\ntimeout_s = 0.5\n"
        "[services.mapping]\npublish_every_s = 1.0\n"
        "[simulation]\nseed = 3\n"
    )
    log = tmp / "run.mcap"
    proc = subprocess.Popen(
        [*HILNAV, "run", "--config", str(cfg), "--log", str(log), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=hilnav_env(),
    )
    op = Bus("operator", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1"])
    seen = Seen()
    for topic in ("pose", "odometry", "diagnostics", "map", "heading", "status"):
        op.subscribe("r1", topic, lambda robot, msg, t=topic: seen.add(t, msg))
    op.on_liveliness(lambda robot, alive: seen.alive.append((robot, alive)))
    yield proc, op, seen, log, port
    op.close()
    if proc.poll() is None:
        proc.kill()
        proc.wait(10)


def test_a_second_session_sees_liveliness_pose_and_the_queryables(running):
    proc, op, seen, _, _ = running
    assert _wait(lambda: ("r1", True) in seen.alive, 30.0), (
        proc.stderr.read() if proc.poll() else ""
    )
    assert _wait(lambda: len(seen.get("pose")) >= 5)
    pose = seen.get("pose")[-1]
    assert isinstance(pose, PoseEstimate) and pose.frame == "map"
    # the robot stands at the office's start pose (1.5, 1.5, 0)
    assert math.hypot(pose.pose.x - 1.5, pose.pose.y - 1.5) < 0.2
    answer = None
    for _ in range(20):
        answer = op.query("r1", "pose", timeout_s=1.0)
        if answer is not None:
            break
    assert isinstance(answer, PoseEstimate) and answer.stamp_ns >= pose.stamp_ns - 10**9
    assert _wait(lambda: len(seen.get("map")) >= 1)
    assert op.query("r1", "map", timeout_s=2.0) is not None
    assert op.query("r1", "info", timeout_s=2.0).robot_class == "Pioneer"


def test_cmd_vel_drives_the_robot_and_its_timeout_stops_it(running):
    _, op, seen, _, _ = running
    assert _wait(lambda: len(seen.get("odometry")) >= 3)
    start = seen.get("odometry")[-1].pose
    end = time.monotonic() + 2.0
    while time.monotonic() < end:
        op.publish_to("r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.3, 0.0, source="operator"))
        time.sleep(0.1)
    moving = seen.get("odometry")[-1]
    assert moving.linear_vel_mps > 0.15
    assert moving.pose.x - start.x > 0.15
    # no more commands: after cmd_vel.timeout_s the daemon stops the robot
    assert _wait(lambda: abs(seen.get("odometry")[-1].linear_vel_mps) < 1e-3, 4.0)


def test_commands_from_outside_the_fleet_and_malformed_ones_are_counted_not_obeyed(running):
    _, op, seen, _, port = running
    raw = zenoh.open(ZenohSettings.loopback(connect_ports=[port]).to_zenoh())
    try:
        before = seen.get("odometry")[-1].pose
        go = b'{"stamp_ns": 1, "linear_mps": 0.5, "angular_radps": 0.0, "source": "mallory"}'
        end = time.monotonic() + 1.5
        while time.monotonic() < end:
            raw.put(key("r1", "cmd_vel"), go, attachment=b"mallory")  # not in the fleet
            raw.put(key("r1", "cmd_vel"), b"\xff{garbage", attachment=b"operator")
            time.sleep(0.1)

        def status():
            d = seen.get("status")
            return d[-1] if d else None

        assert _wait(lambda: status() is not None and status().bus_malformed >= 5, 4.0)
        assert status().bus_foreign >= 5
        after = seen.get("odometry")[-1]
        assert math.hypot(after.pose.x - before.x, after.pose.y - before.y) < 0.02
        assert abs(after.linear_vel_mps) < 1e-3
    finally:
        raw.close()


def test_diagnostics_per_device_at_about_one_hz(running):
    _, _, seen, _, _ = running
    assert _wait(lambda: len([m for m in seen.get("diagnostics") if m.device == "gyro"]) >= 3)
    diags = seen.get("diagnostics")
    devices = {m.device for m in diags}
    assert devices == {"arcos", "ir", "gyro", "gps"}
    st = seen.get("status")[-1]
    assert st.robot == "r1" and st.queue_processed > 100 and st.queue_dropped == 0
    assert st.clock_back_steps == 0  # carried on the wire (the host clock did not step)
    gyro = [m for m in diags if m.device == "gyro"][-1]
    assert gyro.connected and gyro.frames_ok > 100 and 60 < gyro.rate_hz < 140
    ir = [m for m in diags if m.device == "ir"][-1]
    assert ir.connected and 10 < ir.rate_hz < 30


def test_sigterm_exits_0_with_a_closed_log_of_every_topic(running):
    proc, op, seen, log, _ = running
    # what the log must hold, whether or not the tests before this one ran: the robot up
    # for a few seconds (status, map, GPS) and a command from the operator
    assert _wait(lambda: ("r1", True) in seen.alive and len(seen.get("status")) >= 3, 30.0)
    assert _wait(lambda: len(seen.get("map")) >= 1, 10.0)
    op.publish_to("r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.0, 0.0, source="operator"))
    time.sleep(0.3)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "stopped" in out
    # what became of the IR scans: every one accounted for
    line = next(x for x in out.splitlines() if x.startswith("hilnav run: mapping: "))
    n = [int(w) for w in line.replace(",", " ").split() if w.isdigit()]
    assert n[0] > 0 and n[0] == n[1] + n[2] + n[3] + n[4], line
    assert _wait(lambda: ("r1", False) in seen.alive, 5.0)
    counts: dict[str, int] = {}
    schemas: dict[str, str] = {}
    with open(log, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None  # finished file
        for schema, channel, _ in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas.setdefault(channel.topic, schema.name)
    expect = {
        "/r1/odometry": "hilnav.RobotOdometry",
        "/r1/gyro": "hilnav.GyroSample",
        "/r1/gps": "hilnav.GpsFix",
        "/r1/sky": "hilnav.GpsSky",
        "/r1/ir": "hilnav.IrScan",
        "/r1/heading": "hilnav.HeadingEstimate",
        "/r1/pose": "hilnav.PoseEstimate",
        "/r1/map": "foxglove.Grid",
        "/r1/diagnostics": "hilnav.DeviceDiagnostics",
        "/r1/status": "hilnav.DaemonStatus",
        "/r1/cmd_vel": "hilnav.VelocityCommand",
        "/r1/truth": "hilnav.GroundTruth",
        "/r1/info": "hilnav.RobotInfo",
        "/r1/raw/arcos": "hilnav.RawBytes",
        "/r1/raw/ir": "hilnav.RawBytes",
        "/r1/raw/gyro": "hilnav.RawBytes",
        "/r1/raw/gps": "hilnav.RawBytes",
    }
    for topic, schema in expect.items():
        assert counts.get(topic, 0) > 0, (topic, sorted(counts))
        assert schemas[topic] == schema
    # rates: the gyro at 100 Hz, the Pioneer at 10 Hz
    assert counts["/r1/gyro"] > 5 * counts["/r1/odometry"]
    assert Path(log).stat().st_size > 10_000


def test_a_bad_config_gives_its_one_line_message(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text('[devices.arcos]\nport = "sim"\nbaud = "fast"\n')
    r = subprocess.run(
        [*HILNAV, "run", "--config", str(cfg)],
        capture_output=True, text=True, env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "devices.arcos.baud" in lines[0] and "'fast'" in lines[0] and "baud = 9600" in lines[0]
