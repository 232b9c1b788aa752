"""Driver <-> emulated Pioneer over real ptys."""

import json
import math
import os
import subprocess
import time

import pytest
from conftest import HILNAV, hilnav_env, pump

from drivers.arcos.commands import Cmd, encode_command
from drivers.arcos.driver import ArcosDriver, ArcosOptions
from drivers.base import DeviceError
from fakes.pioneer import PioneerEmulator, PioneerFaults
from fakes.runner import FakeRunner
from fakes.world import World
from msgs import Pose2D, RobotOdometry


@pytest.fixture
def fake():
    world = World.from_name("open_field", seed=4)
    world.add_robot("r1", Pose2D(0.0, 0.0, 0.0))
    runner = FakeRunner(world)
    emu = runner.add(PioneerEmulator("r1", seed=4))
    runner.start()
    yield runner, emu
    runner.stop()


def test_handshake_info_and_sips(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"])
    info = d.open()
    assert (info.name, info.robot_class, info.subclass) == ("hilnav-fake", "Pioneer", "p3dx-sh")
    assert info.config["Watchdog"] == 2000
    msgs = [m for m in (pump(d, 0.5),) if m]
    assert msgs and msgs[0].motors_enabled
    diag = d.diagnostics(0)
    assert diag.connected and diag.frames_ok >= 4 and diag.bad_checksums == 0
    d.close()
    time.sleep(0.2)
    assert not emu.session.opened  # CLOSE ended the session


def test_drive_and_pose_matches_truth(fake):
    runner, _ = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    pump(d, 3.0, v=0.4, w=0.0)
    pump(d, 2.0, v=0.2, w=0.5)
    last = pump(d, 1.0, v=0.0, w=0.0)
    truth = runner.world.robots["r1"].pose
    d.close()
    assert last.pose.x > 0.8
    # Encoder odometry vs truth: only slip and quantisation separate them.
    assert math.hypot(last.pose.x - truth.x, last.pose.y - truth.y) < 0.05
    assert abs(math.remainder(last.pose.theta - truth.theta, 2 * math.pi)) < 0.05


def test_wheel_command_vel2(fake):
    runner, _ = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    d.set_wheels(0.2, 0.2)
    last = pump(d, 1.5)
    d.close()
    assert last.left_vel_mps == pytest.approx(0.2) and last.right_vel_mps == pytest.approx(0.2)


def test_watchdog_stops_the_robot_when_the_driver_goes_silent(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    pump(d, 1.0, v=0.3)
    robot = runner.world.robots["r1"]
    assert robot.left_cmd_mps > 0.2
    time.sleep(3.5)  # no reads, no pulses: the firmware's 2 s watchdog trips
    assert emu.session.watchdog_trips == 1
    assert robot.left_cmd_mps == 0.0 and robot.right_cmd_mps == 0.0
    # communication restored (a PULSE): the motion resumes, as the P3 manual says
    last = pump(d, 1.5)
    assert emu.session.watchdog_trips == 1 and last.linear_vel_mps > 0.2
    d.close()


def _session(watchdog_ms: int = 2000):
    from drivers.arcos.commands import ARG_INT, ARG_NINT, Cmd
    from drivers.arcos.params import P3DX_SH
    from fakes.pioneer_config import PioneerConfig
    from fakes.pioneer_motion import DriveModel
    from fakes.pioneer_session import ArcosSession

    sent: list[int] = []
    cfg = PioneerConfig(watchdog_ms=watchdog_ms)
    drive = DriveModel(cfg, P3DX_SH)
    drive.half_base_mm = 165.0
    session = ArcosSession(cfg, drive, lambda cid, data: sent.append(cid))

    def encode_argument(n: int) -> bytes:
        return bytes([ARG_INT if n >= 0 else ARG_NINT, abs(n) & 0xFF, abs(n) >> 8])

    return session, drive, sent, Cmd, encode_argument


@pytest.mark.parametrize(("vel", "rvel"), [(300, 0), (1500, 0), (0, 300), (-1200, 200)])
def test_the_wheels_rest_by_the_watchdog_timeout_after_the_last_byte(vel, rvel):
    """Deceleration included, whatever the speed (a faster stop than the limits if they
    would take longer); firmware time is simulated in 10 ms steps."""
    session, drive, _, cmd, arg = _session()
    for c in (0, 1, 2):
        session.receive(c, b"")
    session.receive(cmd.OPEN, b"")
    for c, n in ((cmd.ENABLE, 1), (cmd.SETA, 3000), (cmd.VEL, vel), (cmd.RVEL, rvel)):
        session.receive(c, arg(n))
    t0 = session.last_rx
    dt, t = 0.01, 0.0
    for _ in range(300):  # 3 s to reach speed (no watchdog yet: packets keep coming)
        drive.step(dt)
        session.last_rx = t0 + t
        t += dt
    assert drive.time_to_stop() > 0.0
    last = session.last_rx
    moving_at = []
    for k in range(300):  # now silence: 3 s, the SIP cycle checks every 100 ms
        now = last + k * dt
        if k % 10 == 0:
            session.check_watchdog(now)
        if max(abs(v) for v in drive.step(dt)) > 0.0:
            moving_at.append(now - last)
    assert moving_at and max(moving_at) < 2.0
    assert session.watchdog_trips == 1


def test_a_bare_open_after_the_handshake_opens_the_session():
    """The manual lists "OPEN 1 none": AMRISim accepts OPEN without an argument."""
    session, _, sent, cmd, _ = _session()
    for c in (0, 1, 2):
        session.receive(c, b"")
    assert sent == [0, 1, 2] and not session.opened
    session.receive(cmd.OPEN, b"")  # ID 1, like SYNC1: after SYNC2 it means OPEN
    assert session.opened and session.sessions == 1 and sent == [0, 1, 2]


def test_keepalive_prevents_watchdog(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    d.set_velocity(0.2, 0.0)
    pump(d, 3.0)  # only reads: the driver's pulses keep the robot going
    assert emu.session.watchdog_trips == 0 and runner.world.robots["r1"].left_cmd_mps > 0.1
    d.close()


def test_reconnect_after_the_port_vanishes_and_returns(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"], ArcosOptions(reconnect_initial_s=0.1))
    d.open()
    pump(d, 0.3)
    emu.vanish()
    pump(d, 0.5)
    assert not d.connected and d.last_error
    emu.reappear()
    last = None
    end = time.monotonic() + 8
    while time.monotonic() < end and (last is None or not d.connected):
        last = pump(d, 0.3) or last
    assert d.connected and d.reconnects == 1 and last is not None
    d.close()


def test_already_open_robot_is_closed_and_resynced(fake):
    runner, emu = fake
    first = ArcosDriver(runner.ports()["arcos"])
    first.open()
    first._t.close()  # the client dies without CLOSE: the robot keeps streaming SIPs
    first._t = None
    second = ArcosDriver(runner.ports()["arcos"])
    info = second.open()
    assert info.name == "hilnav-fake" and emu.session.sessions == 2
    second.close()


def test_corrupted_link_still_delivers(tmp_path):
    world = World.from_name("open_field", seed=1)
    world.add_robot("r1", Pose2D())
    runner = FakeRunner(world)
    runner.add(
        PioneerEmulator(
            "r1", faults=PioneerFaults(corrupt_byte_prob=0.01, drop_packet_prob=0.05), seed=2
        )
    )
    with runner:
        d = ArcosDriver(runner.ports()["arcos"], ArcosOptions(sync_attempts=10))
        d.open()
        n = 0
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            n += sum(isinstance(m, RobotOdometry) for m in d.read(0.1))
        diag = d.diagnostics(0)
        d.close()
    assert n >= 10 and diag.bad_checksums + diag.bytes_skipped > 0


def test_missing_port_gives_a_clear_error():
    with pytest.raises(DeviceError, match="no such port"):
        ArcosDriver("/dev/ttyUSB-does-not-exist").open()


def test_permission_denied_gives_a_clear_error(fake):
    """Open the fake's pty as an unprivileged user (a forked child drops root)."""
    runner, _ = fake
    pts = os.path.realpath(runner.ports()["arcos"])
    os.chmod(pts, 0o600)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: become nobody (if root), try to open, report the message
        try:
            if os.geteuid() == 0:
                os.setgroups([])
                os.setgid(65534)
                os.setuid(65534)
            ArcosDriver(pts).open()
            os.write(w, b"opened")
        except DeviceError as exc:
            os.write(w, str(exc).encode())
        finally:
            os._exit(0)
    os.close(w)
    os.waitpid(pid, 0)
    message = os.read(r, 4096).decode()
    os.close(r)
    assert "permission denied" in message and "dialout" in message


def test_unreachable_tcp_gives_a_clear_error():
    with pytest.raises(DeviceError, match="cannot connect"):
        ArcosDriver("tcp://127.0.0.1:1").open()


def test_recorded_file_is_decoded_without_handshake(tmp_path, fake):
    runner, _ = fake
    rec = bytearray()
    d = ArcosDriver(runner.ports()["arcos"], on_raw=lambda data, ns: rec.extend(data))
    d.open()
    live = [m for m in [pump(d, 1.0, v=0.2)] if m]
    d.close()
    path = tmp_path / "arcos.bin"
    path.write_bytes(bytes(rec))
    f = ArcosDriver(str(path))
    f.open()
    replayed = []
    while not f.eof:
        replayed += [m for m in f.read(0.1) if isinstance(m, RobotOdometry)]
    f.close()
    assert len(replayed) >= 8 and live


def test_cli_fake_and_probe_drive():
    fake = subprocess.Popen(
        [*HILNAV, "fake", "--duration", "20", "--plan", "open_field"],
        stdout=subprocess.PIPE,
        text=True,
        env=hilnav_env(),
    )
    try:
        ports = json.loads(fake.stdout.readline())
        out = subprocess.run(
            [*HILNAV, "probe", "arcos", ports["arcos"], "--drive", "0.3,0", "--seconds", "2"],
            capture_output=True,
            text=True,
            env=hilnav_env(),
            timeout=30,
        )
        assert out.returncode == 0, out.stderr
        lines = [json.loads(x) for x in out.stdout.splitlines()]
        assert lines[0]["robot"]["subclass"] == "p3dx-sh"
        assert len(lines) >= 12 and lines[-1]["x"] > 0.2 and lines[-1]["moving"]
    finally:
        fake.terminate()
        assert fake.wait(10) == 0
        fake.stdout.close()


def test_cli_probe_bad_port_message():
    out = subprocess.run(
        [*HILNAV, "probe", "arcos", "/dev/nope"], capture_output=True, text=True, env=hilnav_env()
    )
    assert out.returncode == 2 and "no such port" in out.stderr and "Traceback" not in out.stderr


def test_pulse_is_a_valid_command_bytes():
    assert encode_command(Cmd.PULSE) == b"\xfa\xfb\x03\x00\x00\x00"
