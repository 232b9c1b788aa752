"""drivers.slcan: python-can's slcan bus reading its port in blocks, on a real pty."""

from __future__ import annotations

import os

import can
import pytest

from drivers.slcan import BlockSlcanBus


@pytest.fixture
def rig():
    """A BlockSlcanBus on the slave side of a pty; the test writes the adapter's bytes to
    the master side (the bus's own commands, O and S6, are read and dropped)."""
    master, slave = os.openpty()
    bus = BlockSlcanBus(os.ttyname(slave), sleep_after_open=0.0, bitrate=500_000)
    os.read(master, 4096)
    yield bus, master
    try:
        bus.shutdown()
    except can.CanError:  # the adapter is gone already
        pass
    for fd in (master, slave):
        try:
            os.close(fd)
        except OSError:
            pass


def test_frames_split_across_reads_and_several_in_one_read(rig):
    bus, master = rig
    assert bus._fd is not None  # the block reader, not python-can's byte reader
    os.write(master, b"t12330102")
    assert bus.recv(timeout=0.05) is None  # half a frame: nothing yet
    os.write(master, b"03\rt4562ABCD\r\at7891FF\r")
    got = [bus.recv(timeout=0.5) for _ in range(3)]
    assert [m.arbitration_id for m in got if m is not None] == [0x123, 0x456, 0x789]
    assert bytes(got[0].data) == b"\x01\x02\x03" and bytes(got[1].data) == b"\xab\xcd"
    assert bus.recv(timeout=0.05) is None


def test_an_extended_frame_and_a_reply_in_the_same_block(rig):
    bus, master = rig
    os.write(master, b"z\rT01ABCDEF2BEEF\r")
    msg = bus.recv(timeout=0.5)
    assert msg is not None and msg.is_extended_id and msg.arbitration_id == 0x1ABCDEF
    assert bytes(msg.data) == b"\xbe\xef"


def test_filters_still_apply(rig):
    bus, master = rig
    bus.set_filters([{"can_id": 0x456, "can_mask": 0x7FF}])
    os.write(master, b"t1231AA\rt4561BB\r")
    msg = bus.recv(timeout=0.5)
    assert msg is not None and msg.arbitration_id == 0x456


def test_a_vanished_adapter_is_an_operation_error(rig):
    bus, master = rig
    os.close(master)
    with pytest.raises(can.CanOperationError):
        bus.recv(timeout=0.5)
