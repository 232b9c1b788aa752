"""The emulated Pioneer against ARIA's own client behaviour, and the driver's fault paths.

``AriaLikeClient`` follows ARIA's source step by step rather than hilnav's driver:
ArRobot::asyncConnectHandler (``WMS2\\r``, flush, SYNC0/1/2 each answered by a packet of
the same ID within 1000 ms, ID 50 during sync -> CLOSE and restart, the SYNC2 strings,
OPEN, CONFIG(1) until a 0x20 packet arrives read as ArRobotConfigPacketReader does),
ArRobotPacketSender::comInt / com2Bytes for commands, and ArRobot::processMotorPacket
for the pose (15-bit deltas with the 0x1000 rule, signed heading difference, addAngle).
Only framing is shared with hilnav (PacketParser is checked against ARIA's checksum
vectors in test_arcos_codec), so a fake that satisfies this client satisfies ARIA.
"""

import math
import os
import socket
import struct
import threading
import time

import pytest
from conftest import pump

from drivers.arcos.commands import encode_command
from drivers.arcos.driver import ArcosDriver, ArcosOptions
from drivers.arcos.packet import PacketParser, frame
from fakes.pioneer import PioneerEmulator
from fakes.pioneer_config import PioneerConfig
from fakes.pty import VirtualSerialPort
from fakes.runner import FakeRunner
from fakes.world import World
from msgs import Pose2D

ANGLE_CONV = 0.001534  # p3dx-sh AngleConvFactor, rad per unit


class AriaLikeClient:
    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        self.parser = PacketParser()
        self.queue: list = []
        self.closes_sent = 0
        self.pose = None  # (x mm, y mm, th deg) as ArRobot's encoder pose
        self.last = None

    def write(self, data: bytes) -> None:
        os.write(self.fd, data)

    def com(self, cmd: int) -> None:
        self.write(frame(cmd))

    def com_int(self, cmd: int, arg: int) -> None:
        # ArRobotPacketSender::comInt: INTARG/NINTARG + magnitude, uByte2 little-endian.
        kind, mag = (0x3B, arg) if arg >= 0 else (0x1B, -arg)
        self.write(frame(cmd, bytes([kind]) + struct.pack("<H", mag)))

    def com_2bytes(self, cmd: int, high: int, low: int) -> None:
        value = ((high & 0xFF) << 8) + (low & 0xFF)
        self.com_int(cmd, struct.unpack("<h", struct.pack("<H", value))[0])  # a short int

    def receive(self, ms: int):
        deadline = time.monotonic() + ms / 1000.0
        while not self.queue:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            import select

            if select.select([self.fd], [], [], left)[0]:
                self.queue += self.parser.feed(os.read(self.fd, 4096), time.monotonic_ns())
        return self.queue.pop(0)

    def connect(self) -> tuple[str, str, str]:
        self.write(b"WMS2\r")
        while self.receive(0) is not None:
            pass
        state, tries = 0, 0
        while state < 3:
            tries += 1
            assert tries < 50, "ARIA gives up after 50 tries"
            self.com(state)
            pkt = self.receive(1000)
            if pkt is None:
                state = 0
            elif pkt.packet_id == 50:  # robot still open: close it, drain, restart
                self.com_int(2, 1)
                self.closes_sent += 1
                end = time.monotonic() + 0.1
                while time.monotonic() < end:
                    self.receive(10)
                state = 0
            elif pkt.packet_id != state:
                state = 0
            else:
                state += 1
                if state == 3:
                    name, cls, sub = pkt.data.split(b"\x00")[:3]
        time.sleep(0.1)  # getCycleTime()
        self.com_int(1, 1)  # OPEN
        self.config = None
        end = time.monotonic() + 1.0
        self.com_int(18, 1)  # ArRobotConfigPacketReader::requestPacket
        while self.config is None and time.monotonic() < end:
            pkt = self.receive(100)
            if pkt is not None and pkt.packet_id == 0x20:
                self.config = self._read_config(pkt.data)
            elif pkt is not None:
                self.motor_packet(pkt)
        return name.decode(), cls.decode(), sub.decode().lower()

    @staticmethod
    def _read_config(data: bytes) -> dict:
        parts = data.split(b"\x00", 3)
        rest = parts[3]
        (_four, rvt, tvt, rat, tat, pwm) = struct.unpack_from("<BHHHHH", rest, 0)
        name_end = rest.index(b"\x00", 11)
        sip_cycle, host_baud = rest[name_end + 1], rest[name_end + 2]
        off = name_end + 4 + 2 + 2 + 1 + 2 + 2
        (watchdog,) = struct.unpack_from("<H", rest, off)
        return {"type": parts[0].decode(), "subtype": parts[1].decode(), "TransVelTop": tvt,
                "RotVelTop": rvt, "SipCycleTime": sip_cycle, "HostBaud": host_baud,
                "Watchdog": watchdog, "name": rest[11:name_end].decode()}  # fmt: skip

    def motor_packet(self, pkt) -> bool:
        if pkt.packet_id not in (0x32, 0x33):
            return False
        x, y = (v & 0x7FFF for v in struct.unpack_from("<HH", pkt.data, 0))
        (th,) = struct.unpack_from("<h", pkt.data, 4)
        if self.last is None:
            self.pose = [0.0, 0.0, math.degrees(ANGLE_CONV * th)]
        else:
            qx, qy, qth = x - self.last[0], y - self.last[1], th - self.last[2]
            qx += -0x8000 if qx > 0x1000 else 0x8000 if qx < -0x1000 else 0
            qy += -0x8000 if qy > 0x1000 else 0x8000 if qy < -0x1000 else 0
            self.pose[0] += qx
            self.pose[1] += qy
            self.pose[2] = math.remainder(self.pose[2] + math.degrees(ANGLE_CONV * qth), 360.0)
        self.last = (x, y, th)
        return True

    def run(self, seconds: float, each_cycle=None) -> int:
        sips = 0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if each_cycle:
                each_cycle()
            cycle_end = time.monotonic() + 0.1
            while (left := cycle_end - time.monotonic()) > 0:
                pkt = self.receive(int(left * 1000))
                if pkt is not None:
                    sips += self.motor_packet(pkt)
        return sips

    def close(self) -> None:
        self.com_int(4, 0)  # ENABLE 0
        self.com_int(2, 1)  # CLOSE
        time.sleep(0.05)
        os.close(self.fd)


@pytest.fixture
def fake():
    world = World.from_name("open_field", seed=5)
    world.add_robot("r1", Pose2D(0.0, 0.0, 0.0))
    runner = FakeRunner(world)
    emu = runner.add(PioneerEmulator("r1", PioneerConfig(name="aria-twin"), seed=5))
    runner.start()
    yield runner, emu
    runner.stop()


def test_aria_connect_sequence_config_and_drive(fake):
    runner, emu = fake
    aria = AriaLikeClient(runner.ports()["arcos"])
    assert aria.connect() == ("aria-twin", "Pioneer", "p3dx-sh")
    assert aria.config["type"] == "Pioneer" and aria.config["subtype"] == "p3dx-sh"
    assert aria.config["name"] == "aria-twin" and aria.config["Watchdog"] == 2000
    assert aria.config["SipCycleTime"] == 100
    aria.com_int(4, 1)  # ENABLE
    # ARIA's state reflection resends VEL/RVEL every cycle; a turn to the left.
    sips = aria.run(2.5, lambda: (aria.com_int(11, 300), aria.com_int(21, 20)))
    aria.com_2bytes(32, -5, -5)  # VEL2: both wheels -100 mm/s (negative bytes)
    sips += aria.run(1.0)
    aria.com_int(11, 0)
    aria.com_int(21, 0)
    sips += aria.run(1.2)
    truth = runner.world.robots["r1"].pose
    aria.close()
    time.sleep(0.15)
    assert sips >= 40 and emu.session.unknown_commands == 0 and not emu.session.opened
    robot = runner.world.robots["r1"]
    assert robot.left_cmd_mps == 0.0 and robot.right_cmd_mps == 0.0
    x, y, th = aria.pose
    assert truth.x > 0.3 and truth.theta > 0.3
    assert math.hypot(x / 1000 - truth.x, y / 1000 - truth.y) < 0.05
    assert abs(math.remainder(math.radians(th) - truth.theta, 2 * math.pi)) < 0.08


def test_aria_closes_a_robot_left_open_and_reconnects(fake):
    runner, emu = fake
    first = AriaLikeClient(runner.ports()["arcos"])
    first.connect()
    os.close(first.fd)  # the program died without CLOSE: SIPs keep coming
    second = AriaLikeClient(runner.ports()["arcos"])
    assert second.connect()[0] == "aria-twin"
    assert second.closes_sent >= 1 and emu.session.sessions == 2
    assert second.run(0.5) >= 3
    second.close()


def test_drive_a_square_and_match_the_truth(fake):
    runner, _ = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    d.send(encode_command(5, 1000) + encode_command(5, -1000) + encode_command(23, 300))
    state = {"odo": pump(d, 0.5), "turned": 0.0, "driven": 0.0}

    def step(v, w):
        prev = state["odo"].pose
        state["odo"] = pump(d, 0.1, v=v, w=w) or state["odo"]
        pose = state["odo"].pose
        state["turned"] += abs(math.remainder(pose.theta - prev.theta, 2 * math.pi))
        state["driven"] += math.hypot(pose.x - prev.x, pose.y - prev.y)
        return pose

    heading = state["odo"].pose.theta
    for _ in range(4):
        p0 = pose = step(0.0, 0.0)
        deadline = time.monotonic() + 6.0
        while math.hypot(pose.x - p0.x, pose.y - p0.y) < 0.3 and time.monotonic() < deadline:
            pose = step(0.4, 0.0)
        heading = math.remainder(heading + math.pi / 2, 2 * math.pi)
        deadline = time.monotonic() + 6.0
        while time.monotonic() < deadline:
            err = math.remainder(heading - pose.theta, 2 * math.pi)
            if abs(err) < math.radians(3):
                break
            pose = step(0.0, max(-1.5, min(1.5, 3.0 * err)))
    last = pump(d, 0.8, v=0.0, w=0.0) or state["odo"]
    truth = runner.world.robots["r1"].pose
    d.close()
    # Four sides and four quarter turns were driven (the control loop's timing aside)...
    assert state["driven"] > 1.0 and state["turned"] > 1.7 * math.pi
    # ...and the driver's pose is the world's within encoder tolerance: the world gives each
    # robot a wheel-base error (~1 %) and slip that the firmware's odometry cannot know.
    assert math.hypot(last.pose.x - truth.x, last.pose.y - truth.y) < 0.06
    assert abs(math.remainder(last.pose.theta - truth.theta, 2 * math.pi)) < 0.15


def test_stop_estop_enable_and_seto(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"])
    d.open()
    assert pump(d, 1.0, v=0.3).moving
    d.estop()
    m = pump(d, 0.5)
    assert m.estop and runner.world.robots["r1"].left_cmd_mps == 0.0
    d.enable_motors(True)
    assert not pump(d, 0.3).estop
    assert pump(d, 1.0, v=0.3).linear_vel_mps > 0.1
    d.stop()
    m = pump(d, 0.5)
    assert m.linear_vel_mps == 0.0 and not m.moving
    assert abs(m.pose.x) > 0.1
    d.reset_odometry()
    m = pump(d, 0.5)
    assert math.hypot(m.pose.x, m.pose.y) < 1e-3 and m.raw["XPOS"] == 0
    d.close()


def test_reconnect_after_the_robot_goes_silent(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"], ArcosOptions(reconnect_initial_s=0.1, sync_attempts=1))
    d.open()
    pump(d, 0.3)
    emu.go_silent()
    end = time.monotonic() + 4.0
    while d.connected and time.monotonic() < end:
        d.read(0.05)
    assert not d.connected and "silent for 2.0 s" in d.last_error
    pump(d, 1.0)  # reconnect attempts fail while the controller is hung
    assert not d.connected and d.reconnects == 0
    emu.recover()
    end = time.monotonic() + 10
    while time.monotonic() < end and not d.connected:
        pump(d, 0.2)
    assert d.connected and d.reconnects == 1 and emu.session.sessions == 2
    assert pump(d, 0.5) is not None
    d.close()


def test_controller_reset_packet_triggers_a_reconnect(fake):
    runner, emu = fake
    d = ArcosDriver(runner.ports()["arcos"], ArcosOptions(reconnect_initial_s=0.1))
    d.open()
    pump(d, 0.3)
    emu.controller_reset()
    end = time.monotonic() + 6
    while time.monotonic() < end and emu.session.sessions < 2:
        pump(d, 0.2)
    assert d.connected and d.reconnects == 1 and emu.session.sessions == 2
    assert "0xFF" in d.last_drop and d.last_error == ""  # reconnected: no error left
    d.close()


def test_driver_over_tcp_like_mobilesim(fake):
    """tcp://host:port: a serial-to-TCP bridge in front of the emulated robot's pty."""
    runner, emu = fake
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    stop = threading.Event()

    def bridge():
        conn, _ = srv.accept()
        fd = os.open(runner.ports()["arcos"], os.O_RDWR | os.O_NOCTTY)
        conn.setblocking(False)
        import select

        while not stop.is_set():
            r, _, _ = select.select([conn, fd], [], [], 0.05)
            try:
                if conn in r:
                    data = conn.recv(4096)
                    if not data:
                        break
                    os.write(fd, data)
                if fd in r:
                    conn.sendall(os.read(fd, 4096))
            except OSError:
                break
        conn.close()
        os.close(fd)

    t = threading.Thread(target=bridge, daemon=True)
    t.start()
    try:
        d = ArcosDriver(f"tcp://127.0.0.1:{port}")
        info = d.open()
        assert info.name == "aria-twin"
        last = pump(d, 1.5, v=0.2)
        d.close()
        assert last is not None and last.linear_vel_mps > 0.05
    finally:
        stop.set()
        t.join(2.0)
        srv.close()


def test_pty_output_is_paced_at_the_baud_rate(tmp_path):
    port = VirtualSerialPort(tmp_path / "paced", baud=9600)
    reader = os.open(port.path, os.O_RDWR | os.O_NOCTTY)
    try:
        t0 = time.monotonic()
        port.write(bytes(480))  # 480 bytes x 10 bits at 9600 baud = 0.5 s
        took = time.monotonic() - t0
        assert took >= 0.49
        got = b""
        while len(got) < 480:
            got += os.read(reader, 4096)
        assert got == bytes(480)
    finally:
        os.close(reader)
        port.close()
