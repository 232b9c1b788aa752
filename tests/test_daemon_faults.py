"""Fault containment of a running daemon (in-process, on the emulated devices): hostile bus
input never moves the robot nor stops the service loop, an exception in a service is
counted and the loop goes on, and a stalled service loop stops the wheels by itself."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time

import pytest
import zenoh

from hilnav.bus import Bus, ZenohSettings, free_tcp_port, key
from hilnav.config import parse_config
from hilnav.daemon import Daemon
from msgs import GroundTruth, VelocityCommand
from tests.conftest import HILNAV, hilnav_env


def _wait(cond, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return bool(cond())


class Truth:
    """The fake world's true speed of r1, received beside the daemon's own loop."""

    def __init__(self) -> None:
        self.last: GroundTruth | None = None
        self.max_speed = 0.0

    def __call__(self, robot: str, msg: GroundTruth) -> None:
        self.last = msg
        self.max_speed = max(self.max_speed, abs(msg.linear_mps))

    def speed(self) -> float:
        return abs(self.last.linear_mps) if self.last is not None else float("nan")


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("faults")
    port = free_tcp_port()
    cfg = parse_config(
        {
            "name": "r1",
            "fleet": ["operator"],
            "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
            "log": {"dir": str(tmp)},
            "cmd_vel": {"timeout_s": 1.0, "stall_s": 0.3},
            "services": {"mapping": {"enabled": False}},
            "simulation": {"seed": 4},
        },
        "<test>",
    )
    d = Daemon(cfg, log_path=tmp / "r1.mcap")
    d.start()
    truth = Truth()
    d.bus.subscribe("r1", "truth", truth)
    op = Bus("operator", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1"])
    raw = zenoh.open(ZenohSettings.loopback(connect_ports=[port]).to_zenoh())
    assert _wait(lambda: truth.last is not None and d.stats.by_topic.get("odometry", 0) > 3, 30)
    yield d, op, raw, truth
    raw.close()
    op.close()
    d.stop()


def test_hostile_commands_never_move_the_robot_nor_stop_the_loop(robot):
    d, op, raw, truth = robot
    truth.max_speed = 0.0
    faults_before = sum(d.stats.faults.values())
    go = {"stamp_ns": 1, "linear_mps": 0.5, "angular_radps": 0.6, "source": "operator"}
    bad = [
        json.dumps({**go, "stamp_ns": 2**64}).encode(),  # the struct.error of the MCAP writer
        json.dumps({**go, "stamp_ns": -5}).encode(),
        json.dumps({**go, "linear_mps": "nan"}).encode(),
        b'{"stamp_ns": 1, "linear_mps": NaN}',
        b'{"stamp_ns": 1, "linear_mps": Infinity}',
        b"[" * 50_000 + b"]" * 50_000,  # RecursionError in json
        b'{"stamp_ns": 1, "source": "' + b"x" * (17 * 1024 * 1024) + b'"}',  # over the limit
        b"\xff\xfe garbage",
        json.dumps({**go, "linear_mps": [1, 2]}).encode(),
    ]
    box = {"stamp_ns": 2**64, "robot": "operator", "x": {"lo": 0, "hi": 1},
           "y": {"lo": 0, "hi": 1}, "theta": {"lo": 0, "hi": 1}}  # fmt: skip
    block = zenoh.CongestionControl.BLOCK  # count every sample: none dropped on the way
    for payload in bad:
        raw.put(key("r1", "cmd_vel"), payload, attachment=b"operator", congestion_control=block)
    raw.put(key("operator", "pose_box"), json.dumps(box).encode(), attachment=b"operator",
            congestion_control=block)  # fmt: skip
    for i in range(10_000):  # a flood of foreign and malformed samples
        raw.put(key("r1", "cmd_vel"), b"{" if i % 2 else json.dumps(go).encode(),
                attachment=b"operator" if i % 2 else b"mallory", congestion_control=block)  # fmt: skip
    assert _wait(lambda: d.bus.stats.malformed >= len(bad) + 1 + 5000, 20.0), d.bus.stats
    assert d.bus.stats.foreign >= 5000
    processed = d.stats.processed
    time.sleep(1.0)
    assert d.stats.processed > processed + 50  # the loop goes on
    assert d._loop_thread.is_alive() and d.motion.alive
    assert truth.max_speed < 1e-3  # the robot never moved
    assert d.motion.gate.received == 0
    assert sum(d.stats.faults.values()) == faults_before


def test_an_exception_in_a_service_is_counted_and_the_loop_goes_on(robot, monkeypatch):
    d, _, _, _ = robot
    real = d.pipeline.feed

    def broken(topic, msg, tag=None):
        raise struct_error("a bug in a service")

    monkeypatch.setattr(d.pipeline, "feed", broken)
    assert _wait(lambda: d.stats.faults.get("services", 0) >= 20, 5.0)
    monkeypatch.setattr(d.pipeline, "feed", real)
    n = d.stats.by_topic.get("odometry", 0)
    assert _wait(lambda: d.stats.by_topic.get("odometry", 0) > n + 3, 5.0)
    assert d._loop_thread.is_alive()
    assert any("a bug in a service" in e for e in d.errors)


class struct_error(Exception):
    pass


def test_a_stalled_service_loop_stops_the_robot(robot, monkeypatch):
    d, op, _, truth = robot
    end = time.monotonic() + 2.5
    while time.monotonic() < end:
        op.publish_to("r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.3, 0.0, source="operator"))
        time.sleep(0.1)
    assert truth.speed() > 0.2, truth.last
    release = threading.Event()
    real = d.pipeline.feed

    def hang(topic, msg, tag=None):
        release.wait(20.0)
        return real(topic, msg, tag)

    monkeypatch.setattr(d.pipeline, "feed", hang)
    stalled_at = time.monotonic()
    try:
        # the operator keeps commanding: the stalled daemon must refuse and stop anyway
        stopped = None
        while time.monotonic() < stalled_at + 6.0:
            op.publish_to(
                "r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.3, 0.0, source="operator")
            )
            if truth.speed() < 1e-3:
                stopped = time.monotonic() - stalled_at
                break
            time.sleep(0.05)
        assert stopped is not None, truth.last
        assert stopped < 2.0  # stall_s (0.3) + the deceleration ramp
        assert d.motion.gate.stalls >= 1 and d.motion.gate.rejected > 0
    finally:
        release.set()
    monkeypatch.setattr(d.pipeline, "feed", real)
    # the loop is back: commands are obeyed again
    assert _wait(lambda: (op.publish_to("r1", "cmd_vel", VelocityCommand(
        time.time_ns(), 0.2, 0.0, source="operator")) or truth.speed() > 0.1), 5.0)  # fmt: skip


def _children(pid: int) -> list[int]:
    out: list[int] = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out += [int(p) for p in f.read().split()]
    except FileNotFoundError:
        pass
    return out


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ", 1)[1].startswith("Z")  # a zombie is gone too
    except FileNotFoundError:
        return True


def test_the_fake_process_dies_with_a_killed_daemon(tmp_path):
    cfg = tmp_path / "r1.toml"
    cfg.write_text(
        f'name = "r1"\n[zenoh]\nlisten = ["tcp/127.0.0.1:{free_tcp_port()}"]\n'
        "[log]\nenabled = false\n[services.mapping]\nenabled = false\n"
    )
    proc = subprocess.Popen(
        [*HILNAV, "run", "--config", str(cfg), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=hilnav_env(),
    )  # fmt: skip
    try:
        assert proc.stdout is not None and " up" in proc.stdout.readline()
        kids = _children(proc.pid)
        assert kids, "the daemon runs its fakes as a child process"
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        assert _wait(lambda: all(_gone(k) for k in kids), 5.0), kids
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        if proc.stdout is not None:
            proc.stdout.close()


def test_a_silent_peer_is_dropped_and_readmitted_when_it_returns(tmp_path):
    from msgs import Interval, PoseBox

    port = free_tcp_port()
    cfg = parse_config(
        {
            "name": "r1",
            "fleet": ["r2"],
            "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
            "log": {"enabled": False},
            "services": {
                "mapping": {"enabled": False},
                "localization": {"peer_timeout_s": 0.5},
            },  # fmt: skip
            "devices": {d: {"enabled": False} for d in ("arcos", "ir", "gyro", "gps")},
        },
        "<test>",
    )
    d = Daemon(cfg)
    d.start()
    r2 = Bus("r2", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1"])
    cp = d.pipeline.localization.cp

    def publish_for(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            box = PoseBox(time.time_ns(), "r2", Interval(0, 1), Interval(0, 1), Interval(0, 0.1))
            r2.publish("pose_box", box)
            time.sleep(0.05)

    try:
        publish_for(1.0)
        assert _wait(lambda: "r2" in cp.peers and d.peers.alive == {"r2"}, 5.0)
        # r2 freezes (its Zenoh session, and so its liveliness token, stay up)
        assert _wait(lambda: "r2" not in cp.peers, 5.0)
        assert d.peers.dropped[-1] == ("r2", "silent for 0.5 s")
        publish_for(0.5)  # back
        assert _wait(lambda: "r2" in cp.peers and "r2" in d.peers.alive, 5.0)
    finally:
        r2.close()
        d.stop()
