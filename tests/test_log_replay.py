"""hilnav replay: deterministic re-run of a log through a pipeline, and from raw bytes."""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from mcap.reader import make_reader

from drivers.cruzcore import encode_packet
from hilnav.log.reader import ReadStats, read_messages, read_metadata
from hilnav.log.writer import LogWriter
from hilnav.replay.replayer import replay
from msgs import (
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    Pose2D,
    PoseEstimate,
    RawBytes,
    RobotOdometry,
)
from tests.conftest import HILNAV, ROOT, hilnav_env

T0 = 5_000_000_000


class DeadReckoning:
    """A small real pipeline: integrates the gyro rate into a heading, odometry into a pose.

    Deterministic and clock-free like hilnav.pipeline.Pipeline; ``gain`` is its parameter.
    """

    def __init__(self, config: object) -> None:
        self.gain = getattr(config, "gain", 1.0)
        self.theta = 0.0
        self.last_ns: int | None = None

    def feed(self, topic: str, msg: object) -> list[tuple[str, object]]:
        if topic == "gyro":
            assert isinstance(msg, GyroSample)
            if self.last_ns is not None:
                self.theta += self.gain * msg.rate_radps * (msg.stamp_ns - self.last_ns) / 1e9
            self.last_ns = msg.stamp_ns
            th = math.remainder(self.theta, 2 * math.pi)
            return [("heading", HeadingEstimate(msg.stamp_ns, th, 1e-4, Pose2D(0, 0, th)))]
        if topic == "odometry":
            assert isinstance(msg, RobotOdometry)
            p = Pose2D(msg.pose.x, msg.pose.y, math.remainder(self.theta, 2 * math.pi))
            return [("pose", PoseEstimate(msg.stamp_ns, p, (0.01,) * 9))]
        return []


@dataclass
class Gain:
    gain: float = 1.0
    source: str = "test"


def _write_input(path: Path, raw: bool = False) -> list[GyroSample]:
    gyros = []
    with LogWriter(path, metadata={"robot": "r1", "plan": "office"}, wall_clock=False) as w:
        for i in range(200):
            t = T0 + i * 10_000_000
            g = GyroSample(t, 0.1 + 0.001 * i, 0.0)
            gyros.append(g)
            w.write("/r1/gyro", g, t)
            if raw:
                pkt = encode_packet(g.rate_radps, 0.01 * i)
                # split packets across reads, like a serial port does
                w.write("/r1/raw/gyro", RawBytes(t, "gyro", pkt[:3]), t)
                w.write("/r1/raw/gyro", RawBytes(t + 1, "gyro", pkt[3:]), t + 1)
            if i % 5 == 0:
                odo = RobotOdometry(t, Pose2D(0.01 * i, 0, 0), 0.2, 0.2, 0.2, 0.0, 12.0, True, True)
                w.write("/r1/odometry", odo, t)
                w.write("/r1/truth", GroundTruth(t, "r1", Pose2D(0.01 * i, 0.0, 0.0)), t)
                # an old output that replay must replace
                w.write("/r1/pose", PoseEstimate(t, Pose2D(99, 99, 0), (0.0,) * 9), t)
            if i == 7:
                w.write_encoded("/r1/acme", "acme.Thing", {"type": "object"}, b'{"k":7}', t)
    return gyros


def test_replay_twice_gives_identical_files(tmp_path: Path) -> None:
    src = tmp_path / "in.mcap"
    _write_input(src)
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    ra = replay(src, a, config=Gain(), pipeline_factory=DeadReckoning, progress=False)
    rb = replay(src, b, config=Gain(), pipeline_factory=DeadReckoning, progress=False)
    assert a.read_bytes() == b.read_bytes()
    assert ra.as_dict()["outputs"] == rb.as_dict()["outputs"] == {"heading": 200, "pose": 40}
    # other parameters, other bytes
    c = tmp_path / "c.mcap"
    replay(src, c, config=Gain(2.0), pipeline_factory=DeadReckoning, progress=False)
    assert c.read_bytes() != a.read_bytes()


def test_replay_replaces_outputs_and_passes_the_rest(tmp_path: Path) -> None:
    src, dst = tmp_path / "in.mcap", tmp_path / "out.mcap"
    _write_input(src)
    rep = replay(src, dst, config=Gain(), pipeline_factory=DeadReckoning, progress=False)
    assert rep.dropped_outputs == 40 and rep.fed == {"gyro": 200, "odometry": 40}
    got = list(read_messages(dst))
    poses = [m for m in got if m.topic == "/r1/pose"]
    assert len(poses) == 40 and all(m.msg.pose.x < 5 for m in poses)  # the new ones
    assert len([m for m in got if m.topic == "/r1/truth"]) == 40
    # the output is logged at the log time of its input
    odo_times = [m.log_time_ns for m in got if m.topic == "/r1/odometry"]
    assert [m.log_time_ns for m in poses] == odo_times
    heading = [m.msg for m in got if m.topic == "/r1/heading"]
    expected = sum(0.1 + 0.001 * i for i in range(1, 200)) * 0.01
    assert heading[-1].theta_rad == pytest.approx(math.remainder(expected, 2 * math.pi))
    meta = read_metadata(dst)["hilnav"]
    assert meta["plan"] == "office" and meta["replay_of"] == "in.mcap"
    with open(dst, "rb") as f:
        acme = [m.data for _, c, m in make_reader(f).iter_messages(topics=["/r1/acme"])]
    assert acme == [b'{"k":7}']


def test_replay_copies_what_it_only_passes_through_and_keeps_recorded_bytes(tmp_path: Path) -> None:
    """A record of the robot's that nothing reads and that has no Foxglove view (raw
    bytes) is copied without decoding; a record it decodes (a fed gyro sample, the truth)
    is logged with the bytes it was recorded with. Same output as decoding and encoding
    every record, which the writer's canonical encoding makes the same bytes."""
    src, dst = tmp_path / "in.mcap", tmp_path / "out.mcap"
    _write_input(src, raw=True)
    rep = replay(src, dst, config=Gain(), pipeline_factory=DeadReckoning, progress=False)
    assert rep.copied == 400 == rep.as_dict()["copied_undecoded"]  # the raw gyro records
    assert rep.read["messages"] == rep.read["decoded"] + rep.copied + 1  # + acme, unknown

    def records(path: Path, topic: str) -> list[tuple[int, bytes]]:
        with open(path, "rb") as f:
            it = make_reader(f).iter_messages(topics=[topic])
            return [(m.log_time, m.data) for _, _, m in it]

    for topic in ("/r1/raw/gyro", "/r1/gyro", "/r1/truth", "/r1/odometry"):
        assert records(dst, topic) == records(src, topic), topic
    assert len(records(dst, "/r1/fox/truth")) == 40  # views still made of decoded ones


def test_replay_from_raw_decodes_the_bytes_again(tmp_path: Path) -> None:
    from hilnav.replay import replayer as replay_mod

    src, dst = tmp_path / "in.mcap", tmp_path / "raw.mcap"
    gyros = _write_input(src, raw=True)

    @dataclass
    class _Ir:
        board_id: int = 1
        adc_bits: int = 10
        vref_v: float = 5.0
        rate_hz: int = 20
        median_window: int = 1
        link: str = "serial"

    @dataclass
    class _Gps:
        datum: tuple[float, float] = (37.5, 127.0)

    @dataclass
    class _Gyro:
        rate_hz: int = 100

    @dataclass
    class _Devices:
        ir: _Ir = field(default_factory=_Ir)
        gps: _Gps = field(default_factory=_Gps)
        gyro: _Gyro = field(default_factory=_Gyro)

    @dataclass
    class _Geometry:
        def ir_mounts_rad(self) -> tuple[tuple[float, float, float], ...]:
            return ((0.2, 0.0, 0.0),)

    @dataclass
    class Cfg(Gain):
        devices: _Devices = field(default_factory=_Devices)
        geometry: _Geometry = field(default_factory=_Geometry)

    rep = replay_mod.replay(
        src, dst, config=Cfg(), from_raw=True, pipeline_factory=DeadReckoning, progress=False
    )
    assert rep.decoded_from_raw == {"gyro": 200}
    got = [m for m in read_messages(dst) if m.topic == "/r1/gyro"]
    assert len(got) == 200
    # the codec's rate resolution is 0.01 deg/s; stamps are those of the completing read
    for g, m in zip(gyros, got, strict=True):
        assert m.msg.rate_radps == pytest.approx(g.rate_radps, abs=math.radians(0.006))
        assert m.msg.stamp_ns == g.stamp_ns + 1
    assert rep.outputs["heading"] == 200


def test_replay_refuses_to_overwrite_its_input(tmp_path: Path) -> None:
    src = tmp_path / "in.mcap"
    _write_input(src)
    with pytest.raises(ValueError, match="differ"):
        replay(src, src, config=Gain(), pipeline_factory=DeadReckoning, progress=False)


def test_replay_with_the_daemon_pipeline_is_deterministic(tmp_path: Path) -> None:
    from tests.logsynth import write_synthetic_log

    src = tmp_path / "run.mcap"
    write_synthetic_log(src, with_map=False)
    outs = []
    for name in ("a.mcap", "b.mcap"):
        proc = subprocess.run(
            [*HILNAV, "replay", str(src), "--out", str(tmp_path / name)],
            capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=240,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        outs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()
    assert outs[0]["fed"]["odometry"] > 0 and sum(outs[0]["outputs"].values()) > 0
    stats = ReadStats()
    assert any(m.topic == "/r1/pose" for m in read_messages(tmp_path / "a.mcap", stats=stats))
    assert stats.malformed == 0
