"""`hilnav play`: a log back on Zenoh in real time, stamps shifted to now, order kept, sent
in the name of each topic's robot; views and raw bytes only when asked; SIGTERM stops a
loop."""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
import zenoh

from hilnav.bus import ZenohSettings, free_tcp_port
from hilnav.log.writer import LogWriter
from hilnav.play import shift_stamps
from msgs import DeviceDiagnostics, GyroSample, Pose2D, PoseEstimate, RawBytes, RobotOdometry
from tests.conftest import HILNAV, ROOT, hilnav_env

T0 = 2_000_000_000  # 1970: far from now, so the shift shows
STEP = 100_000_000  # 10 Hz of log time


def test_shift_stamps_moves_every_stamp_and_nothing_else() -> None:
    obj = {
        "stamp_ns": 5,
        "last_seen_ns": 0,  # "never" stays never
        "count": 7,
        "timestamp": {"sec": 1, "nsec": 999_999_999},
        "inner": [{"t_ns": 10, "x": 1.5}],
        "flag_ns": True,
    }
    assert shift_stamps(obj, 3) == {
        "stamp_ns": 8,
        "last_seen_ns": 0,
        "count": 7,
        "timestamp": {"sec": 2, "nsec": 2},
        "inner": [{"t_ns": 13, "x": 1.5}],
        "flag_ns": True,
    }


def _write_log(path: Path, n: int = 20) -> list[tuple[str, int]]:
    """A log of two robots, with views and raw bytes; the native (key, stamp) in log order."""
    order = []
    with LogWriter(path, wall_clock=False) as w:
        for i in range(n):
            t = T0 + i * STEP
            odo = RobotOdometry(t, Pose2D(0.1 * i, 0, 0), 0.1, 0.1, 0.1, 0, 12, True, True)
            w.write("/r1/odometry", odo, t)
            w.write("/r1/gyro", GyroSample(t + 1, 0.01, 0.0), t + 1)
            w.write("/r1/raw/arcos", RawBytes(t, "arcos", b"\xfa\xfb\x03"), t)
            w.write("/r2/pose", PoseEstimate(t + 2, Pose2D(1.0, 2.0, 0.0), (0.0,) * 9), t + 2)
            order += [
                ("hilnav/r1/odometry", t),
                ("hilnav/r1/gyro", t + 1),
                ("hilnav/r2/pose", t + 2),
            ]
        diag = DeviceDiagnostics(T0 + n * STEP, "arcos", last_seen_ns=0)
        w.write("/r1/diagnostics", diag, T0 + n * STEP)
        order.append(("hilnav/r1/diagnostics", T0 + n * STEP))
    return order


class Listener:
    """A plain Zenoh session listening on a free port, keeping every sample under hilnav/."""

    def __init__(self) -> None:
        self.port = free_tcp_port()
        self.session = zenoh.open(ZenohSettings.loopback(listen_port=self.port).to_zenoh())
        self.lock = threading.Lock()
        self.samples: list[tuple[str, str, dict, int]] = []  # key, sender, payload, received
        self.session.declare_subscriber("hilnav/**", self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        sender = sample.attachment.to_bytes().decode() if sample.attachment else ""
        payload = json.loads(sample.payload.to_bytes())
        with self.lock:
            self.samples.append((str(sample.key_expr), sender, payload, time.time_ns()))

    def wait_for(self, n: int, timeout_s: float = 30.0) -> list[tuple[str, str, dict, int]]:
        end = time.monotonic() + timeout_s
        while len(self.samples) < n and time.monotonic() < end:
            time.sleep(0.05)
        with self.lock:
            return list(self.samples)


@pytest.fixture
def listener():
    li = Listener()
    yield li
    li.session.close()


def _play(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*HILNAV, "play", *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT,
        timeout=120,
    )  # fmt: skip


def test_play_publishes_the_native_messages_in_order_with_stamps_shifted_to_now(
    tmp_path: Path, listener: Listener
) -> None:
    log = tmp_path / "run.mcap"
    order = _write_log(log)
    before = time.time_ns()
    proc = _play(str(log), "--rate", "10", "--connect", f"tcp/127.0.0.1:{listener.port}")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["published"] == len(order) and report["passes"] == 1
    got = listener.wait_for(len(order))
    assert len(got) == len(order)
    # only the native topics, each sent in its robot's name, in the log's order
    assert [k for k, _, _, _ in got] == [k for k, _ in order]
    assert all(sender == key.split("/")[1] for key, sender, _, _ in got)
    # one offset for every stamp of the pass; "never" (0) stays 0
    offset = got[0][2]["stamp_ns"] - order[0][1]
    assert [p["stamp_ns"] - offset for _, _, p, _ in got] == [t for _, t in order]
    assert got[-1][2]["last_seen_ns"] == 0
    # shifted to now: the first stamp lies between the start of play and its reception
    assert before <= got[0][2]["stamp_ns"] <= got[0][3]


def test_views_and_raw_bytes_only_when_topics_name_them(tmp_path: Path, listener: Listener):
    log = tmp_path / "run.mcap"
    _write_log(log, n=5)
    before = time.time_ns()
    proc = _play(
        str(log), "--rate", "100", "--topics", "/r2/fox/*", "/tf", "/r1/raw/arcos",
        "--connect", f"tcp/127.0.0.1:{listener.port}",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["per_topic"] == {"/r1/raw/arcos": 5, "/r2/fox/pose": 5}  # /tf: no robot
    got = listener.wait_for(10)
    assert {k for k, _, _, _ in got} == {"hilnav/r1/raw/arcos", "hilnav/r2/fox/pose"}
    raw = [p for k, _, p, _ in got if k.endswith("raw/arcos")]
    views = [p for k, _, p, _ in got if k.endswith("fox/pose")]
    assert all(p["stamp_ns"] >= before for p in raw)
    # a view's Foxglove time {sec, nsec} is shifted too
    assert all(p["timestamp"]["sec"] * 10**9 + p["timestamp"]["nsec"] >= before for p in views)


def test_loop_plays_again_until_sigterm(tmp_path: Path, listener: Listener) -> None:
    log = tmp_path / "run.mcap"
    _write_log(log, n=3)
    proc = subprocess.Popen(
        [*HILNAV, "play", str(log), "--rate", "20", "--loop", "--topics", "/r2/pose",
         "--connect", f"tcp/127.0.0.1:{listener.port}"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=hilnav_env(), cwd=ROOT,
    )  # fmt: skip
    try:
        got = listener.wait_for(3 * 3)  # three passes of the three poses
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    report = json.loads(out.strip().splitlines()[-1])
    assert report["stopped"] is True and report["passes"] >= 3
    stamps = [p["stamp_ns"] for _, _, p, _ in got]
    assert len(stamps) >= 9 and stamps == sorted(stamps)  # each pass later than the last
    assert {k for k, _, _, _ in got} == {"hilnav/r2/pose"}
