"""Byte links to devices, opened by URL: a serial device, ``tcp://host:port``, or a file.

- a path to a character device (``/dev/ttyUSB0``, a pty): pyserial, 8N1, given baud;
- ``tcp://host:port``: a TCP client (MobileSim/AMRISim serve ARCOS on port 8101);
- a path to a regular file of recorded bytes: read as fast as possible, then EOF.

Every transport has ``read(max_bytes, timeout_s) -> bytes`` (empty on timeout),
``write(data)``, ``close()`` and ``eof`` (a file ran out). Opening failures raise
:class:`drivers.base.DeviceError` naming the port and what to do; a link that breaks
while in use raises :class:`LinkLost` so the driver can reconnect.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import stat
from pathlib import Path

import serial

from drivers.base import DeviceError


class LinkLost(OSError):
    """The link broke while in use (cable pulled, port vanished, peer closed)."""


class Transport:
    url: str = ""
    eof: bool = False

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        raise NotImplementedError

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialTransport(Transport):
    def __init__(self, path: str, baud: int) -> None:
        self.url = path
        try:
            self._port = serial.Serial(path, baudrate=baud, timeout=0, write_timeout=2.0)
        except serial.SerialException as exc:
            raise _open_error(path, exc) from None

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        try:
            fd = self._port.fileno()
            ready, _, _ = select.select([fd], [], [], max(0.0, timeout_s))
            if not ready:
                return b""
            data = os.read(fd, max_bytes)
        except (OSError, serial.SerialException, ValueError, TypeError) as exc:
            raise LinkLost(f"{self.url}: {exc}") from None
        if not data:
            # A readable fd with no bytes: the other end (pty master, USB) is gone.
            raise LinkLost(f"{self.url}: device closed")
        return data

    def write(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except (OSError, serial.SerialException, ValueError, TypeError) as exc:
            raise LinkLost(f"{self.url}: {exc}") from None

    def close(self) -> None:
        try:
            self._port.close()
        except (OSError, serial.SerialException):
            pass


class TcpTransport(Transport):
    def __init__(self, host: str, port: int, connect_timeout_s: float = 3.0) -> None:
        self.url = f"tcp://{host}:{port}"
        try:
            self._sock = socket.create_connection((host, port), timeout=connect_timeout_s)
        except OSError as exc:
            raise DeviceError(
                f"{self.url}: cannot connect ({exc.strerror or exc}); is the simulator or "
                "serial-to-TCP bridge running and listening on that port?"
            ) from None
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        try:
            ready, _, _ = select.select([self._sock], [], [], max(0.0, timeout_s))
            if not ready:
                return b""
            data = self._sock.recv(max_bytes)
        except OSError as exc:
            raise LinkLost(f"{self.url}: {exc}") from None
        if not data:
            raise LinkLost(f"{self.url}: peer closed the connection")
        return data

    def write(self, data: bytes) -> None:
        try:
            self._sock.sendall(data)
        except OSError as exc:
            raise LinkLost(f"{self.url}: {exc}") from None

    def close(self) -> None:
        try:
            self._sock.close()
        except OSError:
            pass


class FileTransport(Transport):
    """Recorded bytes, read as fast as possible; writes are accepted and dropped."""

    def __init__(self, path: str) -> None:
        self.url = path
        try:
            self._f = open(path, "rb")  # noqa: SIM115
        except OSError as exc:
            raise _open_error(path, exc) from None

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        data = self._f.read(max_bytes)
        if not data:
            self.eof = True
        return data

    def write(self, data: bytes) -> None:
        pass

    def close(self) -> None:
        self._f.close()


def _open_error(path: str, exc: Exception) -> DeviceError:
    err = getattr(exc, "errno", None)
    text = str(exc)
    if (
        err == errno.ENOENT
        or "No such file" in text
        or "could not open port" in text
        and not Path(path).exists()
    ):
        return DeviceError(
            f"{path}: no such port; check the cable and the device name "
            "(ls /dev/ttyUSB* /dev/ttyACM* /dev/serial/by-id/)"
        )
    if (err == errno.EACCES or "Permission denied" in text) and Path(path).is_file():
        return DeviceError(f"{path}: permission denied; check the file's permissions (ls -l)")
    if err == errno.EACCES or "Permission denied" in text:
        return DeviceError(
            f"{path}: permission denied; add your user to the 'dialout' group "
            "(sudo usermod -aG dialout $USER, then log in again)"
        )
    if err == errno.EBUSY or "busy" in text.lower():
        return DeviceError(f"{path}: port busy; another program has it open")
    return DeviceError(f"{path}: cannot open: {text}")


def open_transport(url: str, baud: int = 9600) -> Transport:
    """Open a device link by URL (see the module docstring)."""
    if url.startswith("tcp://"):
        host, _, port = url[len("tcp://") :].rpartition(":")
        if not host or not port.isdigit():
            raise DeviceError(f"{url}: expected tcp://HOST:PORT, e.g. tcp://127.0.0.1:8101")
        return TcpTransport(host, int(port))
    path = url[len("file://") :] if url.startswith("file://") else url
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise _open_error(path, FileNotFoundError(errno.ENOENT, "No such file")) from None
    except PermissionError as exc:
        raise _open_error(path, exc) from None
    if stat.S_ISREG(mode):
        return FileTransport(path)
    if stat.S_ISCHR(mode):
        return SerialTransport(path, baud)
    raise DeviceError(f"{path}: neither a serial device nor a file of recorded bytes")
