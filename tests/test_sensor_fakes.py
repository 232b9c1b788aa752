"""Sensor drivers against their emulated twins over real ptys (and slcan on a pty)."""

from __future__ import annotations

import datetime as dt
import itertools
import json
import math
import subprocess
import time

import numpy as np
import pytest

from drivers.cruzcore_driver import CruzCoreDriver
from drivers.irboard import IrBoardConfig
from drivers.irboard.driver import IrCanDriver, IrSerialDriver
from drivers.nmea import NmeaCodec
from drivers.nmea.driver import NmeaDriver
from fakes.gps import DEFAULT_DATUM, GpsEmulator, NmeaReplayEmulator, split_epochs
from fakes.gyro import GyroEmulator
from fakes.irboard import IrBoardEmulator
from fakes.runner import FakeRunner
from fakes.world import World
from fakes.world.gps_model import GpsErrorModel
from fakes.world.gyro_model import GyroErrorModel
from msgs import GpsFix, Pose2D
from tests.conftest import HILNAV, hilnav_env

T0 = dt.datetime(2026, 3, 1, 12, 0, 0, tzinfo=dt.UTC)
_can_channels = itertools.count()


def _collect(driver, seconds: float, want: int | None = None, cls: type = object) -> list:
    """A driver's messages (of class ``cls``) for ``seconds`` or until ``want`` of them."""
    out: list = []
    end = time.monotonic() + seconds
    while time.monotonic() < end and (want is None or len(out) < want):
        out += [m for m in driver.read(0.1) if isinstance(m, cls)]
    return out


@pytest.fixture(scope="module")
def rig():
    """One world: r1 stands still facing walls, r2 spins in place (for the gyro)."""
    world = World.from_name("office", seed=3)
    world.add_robot("r1", Pose2D(1.5, 1.5, 0.3))
    spinner = world.add_robot("r2", Pose2D(3.0, 2.0, 0.0))
    spinner.command_wheels(-0.1, 0.1)
    runner = FakeRunner(world)
    ir = runner.add(IrBoardEmulator("r1", IrBoardConfig(rate_hz=20), seed=1))
    gyro = runner.add(GyroEmulator("r2", 100, GyroErrorModel(seed=2)))
    gps = runner.add(GpsEmulator("r1", 10.0, GpsErrorModel(seed=4), start_utc=T0))
    runner.start()
    yield runner, ir, gyro, gps
    runner.stop()


def test_gyro_driver_configures_rate_and_reads_the_true_yaw_rate(rig):
    runner, _, gyro, _ = rig
    d = CruzCoreDriver(gyro.ports()["gyro"], rate_hz=50)
    d.open()
    try:
        spinner = runner.world.robots["r2"]
        first = _collect(d, 0.1)  # the rate setting applied; the window starts here
        th0 = spinner.pose.theta
        samples = _collect(d, 1.0)
        th1 = spinner.pose.theta
        assert gyro.rate_hz == 50 and gyro.resets >= 1
        assert 25 <= len(samples) <= 75
        # Compare with the truth averaged over the same window (the instantaneous
        # yaw_rate_radps carries the slip model's white noise), and that with the
        # commanded rate, which the slip model's systematic errors change by a few %.
        window_s = (
            (samples[-1].stamp_ns - samples[0].stamp_ns) * 1e-9 * len(samples) / (len(samples) - 1)
        )
        true_mean = (th1 - th0) % (2.0 * math.pi) / window_s
        commanded = (spinner.right_cmd_mps - spinner.left_cmd_mps) / spinner.wheelbase_m
        rates = np.array([s.rate_radps for s in samples])
        assert commanded > 0.5 and abs(true_mean - commanded) < 0.1 * commanded
        assert abs(rates.mean() - true_mean) < 0.03
        angles = [s.angle_rad for s in samples]
        assert all(b >= a - 0.01 for a, b in zip(angles, angles[1:], strict=False))
        assert d.codec.stats.bad_checksums == 0
        # reset re-zeroes the device angle and our unwrapping
        assert d.reset()
        later = _collect(d, 0.5)
        assert abs(later[-1].angle_rad) < 0.5
        assert d.diagnostics(0).frames_ok == len(first) + len(samples) + len(later)
    finally:
        d.close()


def test_gyro_driver_reconnects_when_the_port_vanishes(rig):
    _, _, gyro, _ = rig
    d = CruzCoreDriver(
        gyro.ports()["gyro"], rate_hz=100, silence_timeout_s=0.5, reconnect_initial_s=0.1
    )
    d.open()
    try:
        assert _collect(d, 0.5, want=5)
        gyro.port.vanish()
        _collect(d, 0.4)
        assert not d.connected
        gyro.port.reappear()
        assert _collect(d, 2.0, want=5)
        assert d.reconnects >= 1 and d.connected
    finally:
        d.close()


def test_ir_serial_driver_against_ray_casting(rig):
    runner, ir, _, _ = rig
    cfg = IrBoardConfig(rate_hz=50, median_window=3)
    d = IrSerialDriver(ir.ports()["ir"], cfg)
    d.open()
    try:
        scans = _collect(d, 1.0)
        assert ir.rate_hz == 50 and len(scans) >= 25
        with runner.lock:
            truth = runner.world.ranges("r1", cfg.mounts_array(), 20.0)
        seqs = [s.seq for s in scans]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
        assert d.codec.stats.frames_lost == 0 and d.codec.stats.bad_checksums == 0
        got = np.array([s.ranges_m for s in scans[3:]])
        ok = np.array([[st == "ok" for st in s.status] for s in scans[3:]])
        for k, t in enumerate(truth):
            if 1.1 < t < 3.0:  # where the curve is steep enough to read well
                assert ok[:, k].mean() > 0.9
                assert abs(np.median(got[ok[:, k], k]) - t) < 0.25, (k, t)
            elif t < 0.9:
                assert not np.any(ok[:, k] & (np.abs(got[:, k] - t) < 0.1))
    finally:
        d.close()


def test_gps_driver_reads_truth_with_noise_at_10_hz(rig):
    runner, _, _, gps = rig
    d = NmeaDriver(gps.ports()["gps"], datum=DEFAULT_DATUM)
    d.open()
    try:
        fixes = _collect(d, 1.2, cls=GpsFix)
        assert len(fixes) >= 8
        times = [dt.datetime.fromisoformat(f.time_utc.replace("Z", "+00:00")) for f in fixes]
        steps = {round((b - a).total_seconds(), 2) for a, b in zip(times, times[1:], strict=False)}
        assert steps == {0.1}
        assert times[0] > T0 and all(f.mode == 3 for f in fixes)
        pose = runner.world.robots["r1"].pose
        for f in fixes:
            assert math.hypot(f.east_m - pose.x, f.north_m - pose.y) < 8.0
            assert f.std_lat_m == pytest.approx(gps.error.horizontal_sigma_m, abs=0.01)
    finally:
        d.close()


def _can_rig(link: str, channel: str):
    world = World.from_name("office", seed=5)
    world.add_robot("r1", Pose2D(1.5, 1.5, 0.0))
    runner = FakeRunner(world)
    ir = runner.add(
        IrBoardEmulator("r1", IrBoardConfig(board_id=4, rate_hz=20), link=link, can_channel=channel)
    )
    runner.start()
    return runner, ir


def test_ir_can_driver_over_an_emulated_slcan_adapter_on_a_pty():
    runner, ir = _can_rig("slcan", "")
    try:
        spec = ir.ports()["ir_can"]
        iface, _, path = spec.partition(":")
        assert iface == "slcan"
        cfg = IrBoardConfig(board_id=4, rate_hz=40)
        d = IrCanDriver("slcan", path, cfg, bus_kwargs={"sleep_after_open": 0.0})
        d.open()
        try:
            scans = _collect(d, 1.0)
            assert ir.rate_hz == 40, "SET_RATE went host -> adapter -> board"
            assert ir.adapter.is_open and ir.adapter.bitrate == 500_000
            assert len(scans) >= 15 and all(s.board_id == 4 for s in scans)
            assert len(scans[0].ranges_m) == 6 and d.codec.stats.bad_checksums == 0
        finally:
            d.close()
        end = time.monotonic() + 1.0
        while ir.adapter.is_open and time.monotonic() < end:
            time.sleep(0.02)
        assert not ir.adapter.is_open, "python-can's shutdown sent C (close)"
    finally:
        runner.stop()


def test_ir_can_driver_on_a_python_can_virtual_bus():
    channel = f"hilnav-test-{next(_can_channels)}"
    runner, ir = _can_rig("python-can", channel)
    try:
        d = IrCanDriver("virtual", channel, IrBoardConfig(board_id=4, rate_hz=50))
        d.open()
        try:
            scans = _collect(d, 0.8)
            assert ir.rate_hz == 50 and len(scans) >= 15
            assert d.codec.stats.frames_lost <= 1
        finally:
            d.close()
    finally:
        runner.stop()


def test_ir_can_the_python_can_way_config_table_and_its_own_environment(monkeypatch):
    """[devices.ir.can] reaches can.Bus(...); an empty interface lets python-can's own
    configuration (here its environment variables) choose the bus."""
    from hilnav.config import parse_config
    from hilnav.devices import DEVICES

    channel = f"hilnav-test-{next(_can_channels)}"
    runner, ir = _can_rig("python-can", channel)
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", channel)
    try:
        data = {"devices": {"ir": {"link": "can", "port": "", "can_interface": "",
                                   "board_id": 4, "can": {"receive_own_messages": True}}}}  # fmt: skip
        d = DEVICES["ir"].driver(parse_config(data, "<test>"), None)
        d.open()
        try:
            assert d.bus.receive_own_messages is True  # the table's argument got through
            assert d.bus.channel_info.startswith("Virtual bus channel")
            assert len(_collect(d, 0.6)) >= 5
        finally:
            d.close()
    finally:
        runner.stop()


def test_slcan_adapter_protocol():
    from fakes.slcan import SlcanAdapter

    a = SlcanAdapter.__new__(SlcanAdapter)  # protocol logic only, no pty
    a.is_open, a.listen_only, a.bitrate, a.nodes, a.errors = False, False, None, [], 0
    a.frames_from_host = 0
    got = []
    a.nodes.append(lambda i, d, e: got.append((i, d, e)))
    assert a.handle("S6") == b"\r" and a.bitrate == 500_000
    assert a.handle("t1232ABCD") == b"\x07"  # closed: error
    assert a.handle("O") == b"\r" and a.handle("S4") == b"\x07"  # no bitrate change while open
    assert a.handle("t1232ABCD") == b"z\r" and got == [(0x123, b"\xab\xcd", False)]
    assert a.handle("T000001231FF") == b"Z\r" and got[-1] == (0x123, b"\xff", True)
    assert a.handle("t12") == b"\x07" and a.handle("V") == b"V1013\r"
    assert a.handle("C") == b"\r" and not a.is_open


def test_replay_as_fast_as_possible_matches_the_log(shared_dir, tmp_path):
    log = shared_dir / "data/gpsd/mt3339.log"
    expected = NmeaCodec()
    want = [
        m for m in expected.feed(log.read_bytes(), 0) + expected.flush() if isinstance(m, GpsFix)
    ]
    runner = FakeRunner(World.from_name("open_field"), link_dir=tmp_path)
    rep = runner.add(NmeaReplayEmulator(log, fast=True))
    runner.start()
    try:
        d = NmeaDriver(rep.ports()["gps"])
        d.open()
        got = _collect(d, 3.0, want=len(want) - 1, cls=GpsFix)
        d.close()
    finally:
        runner.stop()
    assert [f.time_utc for f in got] == [f.time_utc for f in want][: len(got)]
    assert len(got) >= len(want) - 1  # the last epoch waits for the next one (live stream)


def test_replay_keeps_the_logs_own_pace(tmp_path):
    from drivers.nmea.writer import epoch_sentences
    from msgs import GpsFix

    fix = GpsFix(0, lat_deg=1.0, lon_deg=2.0, alt_msl_m=3.0, mode=3, satellites=8, hdop=1.0)
    raw = b"".join(
        epoch_sentences(fix, T0 + dt.timedelta(milliseconds=200 * k), types=("GGA", "RMC"))
        for k in range(5)
    )
    path = tmp_path / "paced.nmea"
    path.write_bytes(b"# a comment line\n" + raw)
    assert len(split_epochs(path.read_bytes())) == 5
    runner = FakeRunner(World.from_name("open_field"), link_dir=tmp_path)
    rep = runner.add(NmeaReplayEmulator(path))
    runner.start()
    try:
        d = NmeaDriver(rep.ports()["gps"])
        d.open()
        t0 = time.monotonic()
        got = _collect(d, 2.0, want=4, cls=GpsFix)
        took = time.monotonic() - t0
        d.close()
    finally:
        runner.stop()
    assert len(got) == 4 and took >= 0.6  # 4 gaps of 0.2 s before the 5th epoch


def test_cli_fake_replay_and_probe_gps(shared_dir, tmp_path):
    log = shared_dir / "data/gpsd/bu353s4.log"
    fake = subprocess.Popen(
        HILNAV + ["fake", "--devices", "gps", "--replay", f"gps={log}", "--replay-fast",
                  "--duration", "8", "--link-dir", str(tmp_path)],
        stdout=subprocess.PIPE, text=True, env=hilnav_env(),
    )  # fmt: skip
    try:
        ports = json.loads(fake.stdout.readline())
        assert set(ports) == {"gps"}
        out = subprocess.run(
            HILNAV + ["probe", "gps", ports["gps"], "--count", "3", "--seconds", "5"],
            capture_output=True, text=True, env=hilnav_env(), timeout=20,
        )  # fmt: skip
    finally:
        fake.terminate()
        fake.wait(timeout=5)
    assert out.returncode == 0, out.stderr
    objs = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(objs) == 3
    assert objs[0]["time"] == "2014-12-31T03:07:19.000Z" and objs[0]["mode"] == 3
    assert objs[0]["lat"] == pytest.approx(-37.784788333, abs=1e-8)
    assert objs[0]["lon"] == pytest.approx(175.314896667, abs=1e-8)
    assert objs[0]["alt"] == pytest.approx(59.9)


def test_cli_probe_reads_a_file_and_reports_bad_ports(shared_dir, tmp_path):
    from drivers.cruzcore import encode_packet

    gyro_file = tmp_path / "gyro.bin"
    gyro_file.write_bytes(b"\x00\x01" + b"".join(encode_packet(0.1, 0.01 * k) for k in range(5)))
    out = subprocess.run(HILNAV + ["probe", "gyro", str(gyro_file)], capture_output=True,
                         text=True, env=hilnav_env(), timeout=20)  # fmt: skip
    rows = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(rows) == 5 and rows[4]["angle_rad"] == pytest.approx(0.04, abs=2e-4)
    bad = subprocess.run(HILNAV + ["probe", "ir", str(tmp_path / "nope")], capture_output=True,
                         text=True, env=hilnav_env(), timeout=20)  # fmt: skip
    assert bad.returncode == 2 and "no such port" in bad.stderr


def test_cli_fake_serves_all_four_devices_and_probe_reads_each(tmp_path):
    """Default ``hilnav fake``: arcos, ir, gyro, gps on ptys; probe reads ir, gyro and gps."""
    fake = subprocess.Popen(
        HILNAV + ["fake", "--plan", "paper_room", "--gps-rate", "5", "--duration", "25",
                  "--link-dir", str(tmp_path)],
        stdout=subprocess.PIPE, text=True, env=hilnav_env(),
    )  # fmt: skip
    try:
        ports = json.loads(fake.stdout.readline())
        assert set(ports) == {"arcos", "ir", "gyro", "gps"}
        rows = {}
        for dev in ("ir", "gyro", "gps"):
            out = subprocess.run(
                HILNAV + ["probe", dev, ports[dev], "--count", "3", "--seconds", "8"],
                capture_output=True, text=True, env=hilnav_env(), timeout=30,
            )  # fmt: skip
            assert out.returncode == 0, out.stderr
            rows[dev] = [json.loads(line) for line in out.stdout.splitlines()]
    finally:
        fake.terminate()
        fake.wait(timeout=10)
        fake.stdout.close()
    assert len(rows["ir"]) == 3 and len(rows["ir"][0]["ranges_m"]) == 6
    assert len(rows["gyro"]) == 3 and "rate_radps" in rows["gyro"][0]
    gps = rows["gps"][-1]
    assert gps["mode"] == 3 and gps["time"].endswith("Z") and -90 <= gps["lat"] <= 90


def test_cli_fake_ir_on_can_behind_slcan_and_probe_in_another_process(tmp_path):
    fake = subprocess.Popen(
        HILNAV + ["fake", "--devices", "ir", "--ir-link", "slcan", "--plan", "paper_room",
                  "--duration", "20", "--link-dir", str(tmp_path)],
        stdout=subprocess.PIPE, text=True, env=hilnav_env(),
    )  # fmt: skip
    try:
        ports = json.loads(fake.stdout.readline())
        assert set(ports) == {"ir_can"} and ports["ir_can"].startswith("slcan:")
        out = subprocess.run(
            HILNAV + ["probe", "ir", ports["ir_can"], "--count", "3", "--seconds", "8"],
            capture_output=True, text=True, env=hilnav_env(), timeout=30,
        )  # fmt: skip
    finally:
        fake.terminate()
        fake.wait(timeout=10)
        fake.stdout.close()
    assert out.returncode == 0, out.stderr
    scans = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(scans) == 3 and all(len(s["status"]) == 6 for s in scans)


def test_cli_fake_takes_the_robot_config_file(tmp_path):
    cfg = tmp_path / "robot.toml"
    cfg.write_text(
        'name = "r7"\n[devices.gps]\nenabled = false\n[devices.ir]\nlink = "serial"\n'
        'rate_hz = 40\n[simulation]\nplan = "paper_room"\nseed = 3\n'
    )
    out = subprocess.run(
        HILNAV + ["fake", "--config", str(cfg), "--duration", "1", "--link-dir", str(tmp_path)],
        capture_output=True, text=True, env=hilnav_env(), timeout=30,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert set(json.loads(out.stdout.splitlines()[0])) == {"arcos", "ir", "gyro"}
    # A command-line option wins over the file; a bad file names the key.
    out = subprocess.run(
        HILNAV + ["fake", "--config", str(cfg), "--devices", "gps", "--duration", "1",
                  "--link-dir", str(tmp_path)],
        capture_output=True, text=True, env=hilnav_env(), timeout=30,
    )  # fmt: skip
    assert set(json.loads(out.stdout.splitlines()[0])) == {"gps"}
    cfg.write_text("[simulation]\nplann = 1\n")
    bad = subprocess.run(HILNAV + ["fake", "--config", str(cfg)], capture_output=True,
                         text=True, env=hilnav_env(), timeout=30)  # fmt: skip
    assert bad.returncode == 2 and "plann" in bad.stderr and "Traceback" not in bad.stderr
