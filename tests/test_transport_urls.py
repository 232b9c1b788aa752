"""Ports the pyserial way: any ``serial_for_url`` URL reaches the drivers, and
``hilnav probe --list`` describes serial ports and guesses their device."""

from __future__ import annotations

import socket
import threading

import pytest
from conftest import pump
from serial.tools.list_ports_common import ListPortInfo

from drivers.arcos.driver import ArcosDriver
from drivers.base import DeviceError
from drivers.transport import open_transport
from fakes.pioneer import PioneerEmulator
from fakes.runner import FakeRunner
from fakes.world import World
from hilnav.commands.probe import port_row
from hilnav.devices import guess_device
from msgs import Pose2D


@pytest.fixture
def pioneer():
    world = World.from_name("open_field", seed=2)
    world.add_robot("r1", Pose2D(0.0, 0.0, 0.0))
    runner = FakeRunner(world)
    runner.add(PioneerEmulator("r1", seed=2))
    runner.start()
    yield runner.ports()["arcos"]
    runner.stop()


def test_spy_url_drives_the_robot_and_logs_the_traffic(pioneer, tmp_path):
    log = tmp_path / "spy.txt"
    d = ArcosDriver(f"spy://{pioneer}?file={log}")
    info = d.open()
    assert info is not None and info.robot_class == "Pioneer"
    last = pump(d, 1.0, v=0.2)
    d.close()
    assert last is not None and last.linear_vel_mps > 0.05
    text = log.read_text()
    assert "TX" in text.upper() or "tx" in text  # pyserial's spy logged both directions


def _bridge(pty_path: str) -> tuple[int, threading.Event]:
    """A one-connection TCP-to-pty bridge, as ser2net would be."""
    srv = socket.create_server(("127.0.0.1", 0))
    done = threading.Event()

    def serve() -> None:
        conn, _ = srv.accept()
        port = open_transport(pty_path, 9600)
        conn.settimeout(0.01)
        while not done.is_set():
            data = port.read(4096, 0.01)
            if data:
                conn.sendall(data)
            try:
                got = conn.recv(4096)
            except TimeoutError:
                continue
            if not got:
                break
            port.write(got)
        conn.close()
        port.close()
        srv.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv.getsockname()[1], done


@pytest.mark.parametrize("scheme", ["socket", "tcp"])
def test_socket_urls_reach_the_robot_through_a_bridge(pioneer, scheme):
    port, done = _bridge(pioneer)
    try:
        d = ArcosDriver(f"{scheme}://127.0.0.1:{port}")
        assert d.open() is not None
        assert pump(d, 0.5) is not None
        d.close()
    finally:
        done.set()


def test_url_errors_name_the_url_and_the_fix():
    with pytest.raises(DeviceError, match="tcp://127.0.0.1:1: cannot connect.*listening"):
        open_transport("tcp://127.0.0.1:1")
    with pytest.raises(DeviceError, match="hwgrep://ffff:ffff: no serial port matches"):
        open_transport("hwgrep://ffff:ffff")
    t = open_transport("loop://")
    t.write(b"ping")
    assert t.read(64, 0.2) == b"ping"
    t.close()


def _info(device: str, vid: int | None, pid: int | None, description: str) -> ListPortInfo:
    p = ListPortInfo(device, skip_link_detection=True)
    p.vid, p.pid, p.description = vid, pid, description
    return p


def test_probe_list_describes_ports_and_guesses_the_device():
    ublox = _info("/dev/ttyACM0", 0x1546, 0x01A8, "u-blox GNSS receiver")
    row = port_row(ublox, {"/dev/ttyACM0": ["/dev/serial/by-id/usb-u-blox_GNSS-if00"]})
    assert row["usb"] == "1546:01a8" and row["guess"] == "gps"
    assert row["by_id"] == ["/dev/serial/by-id/usb-u-blox_GNSS-if00"]
    assert guess_device(0x16D0, 0x117E, "CANable") == "ir"
    assert "USB-serial adapter" in guess_device(0x0403, 0x6001, "FT232R USB UART")
    assert guess_device(None, None, "n/a") == ""
