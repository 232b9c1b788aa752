"""A log's raw CAN frames exported with python-can's writers and read back by its
readers, frame for frame; the IR codec decodes the read-back frames into the same scans."""

from __future__ import annotations

import subprocess

import can
import pytest

from drivers.irboard import IrBoardConfig
from drivers.irboard.canframe import pack_raw_frame, pack_sample
from drivers.irboard.codec import IrCanCodec
from drivers.irboard.serialframe import RawSample
from hilnav.log.writer import LogWriter
from msgs import RawBytes
from tests.conftest import HILNAV, hilnav_env

T0 = 1_700_000_000_000_000_000


def _frames(n: int = 30) -> list[tuple[int, bytes, bool, int]]:
    out = []
    for k in range(n):
        arb, data = pack_sample(RawSample(1, k & 0xF, 10, tuple(100 + 7 * c + k for c in range(6))))
        out.append((arb, data, False, T0 + k * 50_000_000))
    out.append((0x18FF00AB, b"\x01\x02", True, T0 + n * 50_000_000))  # an extended-id frame
    return out


@pytest.fixture
def can_log(tmp_path):
    path = tmp_path / "r1.mcap"
    with LogWriter(path, metadata={"robot": "r1"}) as w:
        for arb, data, ext, t in _frames():
            w.write("/r1/raw/ir", RawBytes(t, "ir", pack_raw_frame(arb, data, ext)), t)
        w.write("/r1/raw/gyro", RawBytes(T0, "gyro", b"\xff\x00junk"), T0)
    return path


@pytest.mark.parametrize("ext", ["asc", "blf", "csv", "trc"])
def test_exported_frames_read_back_with_python_can(can_log, tmp_path, ext):
    out = tmp_path / f"frames.{ext}"
    r = subprocess.run([*HILNAV, "log", "export-can", str(can_log), str(out)],
                       capture_output=True, text=True, env=hilnav_env(), timeout=60)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "31 CAN frames" in r.stdout
    back = list(can.LogReader(str(out)))
    want = _frames()
    assert [(m.arbitration_id, bytes(m.data), m.is_extended_id) for m in back] == [
        (a, d, e) for a, d, e, _ in want
    ]
    # every format keeps the spacing (.asc starts its clock at the first frame)
    t0, b0 = want[0][3], back[0].timestamp
    assert all(
        abs((m.timestamp - b0) - (t - t0) * 1e-9) < 1e-3
        for m, (*_, t) in zip(back, want, strict=True)
    )
    codec = IrCanCodec(IrBoardConfig(board_id=1))
    scans = [codec.feed_frame(m.arbitration_id, bytes(m.data), 0, m.is_extended_id) for m in back]
    assert sum(s is not None for s in scans) == 30


def test_a_serial_ir_log_has_no_can_frames(tmp_path):
    path = tmp_path / "s.mcap"
    toml = '[devices.ir]\nlink = "serial"\n'
    with LogWriter(path, metadata={"robot": "r1", "config_toml": toml}) as w:
        w.write("/r1/raw/ir", RawBytes(T0, "ir", b"\x00" * 12), T0)
    r = subprocess.run([*HILNAV, "log", "export-can", str(path), str(tmp_path / "x.asc")],
                       capture_output=True, text=True, env=hilnav_env(), timeout=60)  # fmt: skip
    assert r.returncode == 2 and "serial link" in r.stderr
