"""IR ADC board drivers: serial (any byte link) and CAN (any python-can interface).

The serial driver sends SET_RATE on connect. The CAN driver opens a python-can bus —
``slcan`` (a USB-CAN adapter on a serial port, channel = the port path; python-can's
slcan read in blocks: drivers.slcan), ``virtual``
(in-process), ``socketcan`` (Linux, channel = ``can0``) or any other interface — filters
its board's sample id, sends SET_RATE, and reopens the bus when it fails.
"""

from __future__ import annotations

import time
from typing import Any

import can

from drivers.base import Clock, DeviceError, LinkDiagnostics, RawHook, wall_clock_ns
from drivers.irboard.canframe import SAMPLE_ID_BASE, pack_raw_frame, pack_set_rate
from drivers.irboard.codec import IrCanCodec, IrSerialCodec
from drivers.irboard.convert import IrBoardConfig
from drivers.irboard.serialframe import set_rate_command
from drivers.reconnect import Reconnect, local_path
from drivers.slcan import BlockSlcanBus
from drivers.stream import StreamDriver
from msgs import IrScan


class IrSerialDriver(StreamDriver):
    device = "ir"

    def __init__(
        self,
        url: str,
        config: IrBoardConfig | None = None,
        baud: int = 115200,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
        **kw: float,
    ) -> None:
        self.config = config or IrBoardConfig()
        super().__init__(url, IrSerialCodec(self.config), baud, clock, on_raw, **kw)

    def _on_open(self) -> None:
        assert self._t is not None
        self._t.write(set_rate_command(self.config.board_id, self.config.rate_hz))

    def set_rate(self, rate_hz: int) -> bool:
        return self.write(set_rate_command(self.config.board_id, rate_hz))


class IrCanDriver(LinkDiagnostics):
    """One board on a CAN bus reached through python-can (see the module docstring)."""

    device = "ir"

    def __init__(
        self,
        interface: str,
        channel: str,
        config: IrBoardConfig | None = None,
        bitrate: int = 500_000,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
        silence_timeout_s: float = 3.0,
        bus_kwargs: dict[str, Any] | None = None,
    ) -> None:
        self.interface = interface
        self.channel = channel
        self.config = config or IrBoardConfig()
        self.bitrate = bitrate
        self.clock = clock
        self.on_raw = on_raw
        self.silence_timeout_s = silence_timeout_s
        self.bus_kwargs = dict(bus_kwargs or {})
        self.codec = IrCanCodec(self.config)
        self.bus: can.BusABC | None = None
        self.connected = False
        self.reconnects = 0
        self.last_error = ""
        self._last_rx = 0.0
        self._rc = Reconnect(path=local_path(channel) if interface == "slcan" else None)
        self._last_seen_ns = 0

    def open(self) -> None:
        kw = dict(self.bus_kwargs)
        if self.interface == "slcan":
            kw.setdefault("sleep_after_open", 0.1)
            kw.setdefault("bitrate", self.bitrate)
        elif self.interface not in ("virtual", ""):
            kw.setdefault("bitrate", self.bitrate)
        can_filters = [{"can_id": SAMPLE_ID_BASE + self.config.board_id, "can_mask": 0x7FF}]
        if self.interface:  # else python-can's own config file / environment decide
            kw["interface"] = self.interface
        if self.channel:
            kw["channel"] = self.channel
        try:
            if kw.get("interface") == "slcan" and "channel" in kw:
                del kw["interface"]
                self.bus = BlockSlcanBus(can_filters=can_filters, **kw)
            else:
                self.bus = can.Bus(can_filters=can_filters, **kw)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise DeviceError(
                f"CAN {self.interface}:{self.channel}: cannot open ({exc}); check the "
                "interface name (slcan, socketcan, virtual, ...) and the channel (the "
                "adapter's serial port for slcan, e.g. /dev/ttyACM0; can0 for socketcan)"
            ) from None
        self.connected = True
        self._last_rx = time.monotonic()
        self._rc.succeeded()
        self.last_error = ""
        self.set_rate(self.config.rate_hz)

    def set_rate(self, rate_hz: int) -> bool:
        if self.bus is None:
            return False
        arb, data = pack_set_rate(self.config.board_id, rate_hz)
        try:
            self.bus.send(can.Message(arbitration_id=arb, data=data, is_extended_id=False))
            return True
        except (can.CanError, OSError) as exc:
            self.last_error = str(exc)
            return False

    def read(self, timeout_s: float) -> list[IrScan]:
        if not self.connected:
            if self._rc.due(time.monotonic()):
                try:
                    self.open()
                    self.reconnects += 1
                except DeviceError as exc:
                    self.last_error = str(exc)
                    self._rc.failed(time.monotonic())
            if not self.connected:
                time.sleep(self._rc.wait_s(time.monotonic(), timeout_s))
                return []
        assert self.bus is not None
        out: list[IrScan] = []
        deadline = time.monotonic() + timeout_s
        try:
            while True:
                # wait for the first scan; once one came, only drain what is queued
                left = 0.0 if out else max(0.0, deadline - time.monotonic())
                msg = self.bus.recv(timeout=left)
                if msg is None:
                    break
                stamp = self.clock()
                if self.on_raw:
                    self.on_raw(
                        pack_raw_frame(msg.arbitration_id, msg.data, msg.is_extended_id), stamp
                    )
                if msg.is_error_frame or msg.is_remote_frame:
                    continue
                scan = self.codec.feed_frame(
                    msg.arbitration_id, bytes(msg.data), stamp, msg.is_extended_id
                )
                if scan is not None:
                    self._last_rx = time.monotonic()
                    self._last_seen_ns = stamp
                    out.append(scan)
        except (can.CanError, OSError, ValueError) as exc:
            self._drop(f"CAN {self.interface}:{self.channel}: {exc}")
            return out
        if time.monotonic() - self._last_rx > self.silence_timeout_s:
            self._drop(f"CAN {self.interface}:{self.channel}: board silent")
        return out

    def fileno(self) -> int | None:
        """The slcan adapter's port descriptor while the bus is up (for a selector that
        calls ``read(0)`` when it is readable, and again while :meth:`buffered`); None
        for other interfaces (read them with a timeout)."""
        bus = self.bus
        if self.connected and isinstance(bus, BlockSlcanBus):
            return bus.fd
        return None

    def buffered(self) -> bool:
        """Complete lines already read from the adapter and not yet decoded."""
        bus = self.bus
        return isinstance(bus, BlockSlcanBus) and bus.has_line()

    def _drop(self, why: str) -> None:
        self.last_error = why
        self.connected = False
        self.close()
        self._rc.lost(time.monotonic())

    def close(self) -> None:
        self.connected = False
        if self.bus is not None:
            try:
                self.bus.shutdown()
            except (can.CanError, OSError):
                pass
            self.bus = None
