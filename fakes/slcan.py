"""An emulated slcan (Lawicel ASCII) USB-CAN adapter on a virtual serial port.

The host side is what python-can's ``slcan`` interface (and can-utils' slcand) speak:
commands end with CR; the adapter answers CR (ok) or BEL (error). Supported: ``O`` open,
``L`` open listen-only, ``C`` close, ``S0``-``S8`` bit rate, ``sXXYY`` BTR registers,
``V`` version (``V1013``), ``v`` firmware, ``N`` serial number, ``F`` status flags,
``Z0/Z1`` timestamps (accepted, off), ``t/T/r/R`` transmit (answered ``z``/``Z`` while
open), ``Y`` CAN FD data rate (accepted, unused). Received frames go to the host as
``tIIILDD..`` / ``TIIIIIIIILDD..`` lines while the channel is open.

The CAN side is a list of node callbacks: a node (the fake IR board) calls
:meth:`SlcanAdapter.deliver` to put a frame on the bus and registers ``on_frame`` to
receive what the host transmits. The pty is served by its own thread.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

from fakes.pty import VirtualSerialPort

FrameHandler = Callable[[int, bytes, bool], None]
BITRATES = {0: 10_000, 1: 20_000, 2: 50_000, 3: 100_000, 4: 125_000, 5: 250_000,
            6: 500_000, 7: 750_000, 8: 1_000_000, 9: 83_300}  # fmt: skip

OK = b"\r"
ERR = b"\x07"


class SlcanAdapter:
    def __init__(self, link: str | Path) -> None:
        self.port = VirtualSerialPort(link)
        self.is_open = False
        self.listen_only = False
        self.bitrate: int | None = None
        self.nodes: list[FrameHandler] = []
        self.frames_to_host = 0
        self.frames_from_host = 0
        self.frames_dropped = 0
        self.errors = 0
        self._buf = bytearray()
        self._wlock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="fake-slcan", daemon=True)

    @property
    def path(self) -> str:
        return self.port.path

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.port.close()

    # -- CAN side -----------------------------------------------------------------------
    def deliver(self, arb_id: int, data: bytes, extended: bool = False) -> None:
        """A node puts a frame on the bus: the host sees it if the channel is open."""
        if not self.is_open:
            self.frames_dropped += 1
            return
        if extended:
            line = f"T{arb_id:08X}{len(data)}{data.hex().upper()}\r"
        else:
            line = f"t{arb_id:03X}{len(data)}{data.hex().upper()}\r"
        if self._send(line.encode("ascii")):
            self.frames_to_host += 1
        else:
            self.frames_dropped += 1

    def _send(self, data: bytes) -> bool:
        with self._wlock:
            fd = self.port.master
            if fd is None:
                return False
            try:
                return os.write(fd, data) == len(data)
            except OSError:  # buffer full (nobody reading) or port gone: frame lost
                return False

    # -- host side ----------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stop.is_set():
            data = self.port.read(0.05)
            if not data:
                continue
            self._buf += data
            while True:
                cr = self._buf.find(b"\r")
                if cr < 0:
                    if len(self._buf) > 64:  # garbage without CR
                        self._buf.clear()
                        self.errors += 1
                    break
                line = bytes(self._buf[:cr]).lstrip(b"\n")
                del self._buf[: cr + 1]
                self._send(self.handle(line.decode("ascii", "replace")))

    def handle(self, cmd: str) -> bytes:
        """The adapter's answer to one command line (without its CR)."""
        if not cmd:
            return OK
        c, arg = cmd[0], cmd[1:]
        if c == "O" or c == "L":
            if self.is_open:
                return ERR
            self.is_open, self.listen_only = True, c == "L"
            return OK
        if c == "C":
            self.is_open = False
            return OK
        if c == "S":
            if self.is_open or not arg.isdigit() or int(arg) not in BITRATES:
                return ERR
            self.bitrate = BITRATES[int(arg)]
            return OK
        if c == "s":
            return ERR if self.is_open or len(arg) != 4 else OK
        if c == "V":
            return b"V1013\r"
        if c == "v":
            return b"vhilnav-slcan-emu\r"
        if c == "N":
            return b"NHN01\r"
        if c == "F":
            return b"F00\r"
        if c in "ZYMm":
            return OK
        if c in "tTrR":
            return self._transmit(c, arg)
        self.errors += 1
        return ERR

    def _transmit(self, c: str, arg: str) -> bytes:
        if not self.is_open or self.listen_only:
            return ERR
        ext = c in "TR"
        n = 8 if ext else 3
        try:
            arb = int(arg[:n], 16)
            dlc = int(arg[n])
            data = b"" if c in "rR" else bytes.fromhex(arg[n + 1 : n + 1 + 2 * dlc])
        except (ValueError, IndexError):
            self.errors += 1
            return ERR
        if dlc > 8 or (c in "tT" and len(data) != dlc):
            self.errors += 1
            return ERR
        self.frames_from_host += 1
        for node in list(self.nodes):
            node(arb, data, ext)
        return b"Z\r" if ext else b"z\r"
