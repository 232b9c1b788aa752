"""Byte links to devices, opened by URL the pyserial way, or a file of recorded bytes.

- a path to a character device (``/dev/ttyUSB0``, a pty): pyserial, 8N1, given baud;
- any pyserial URL (``serial.serial_for_url``): ``socket://host:port`` (MobileSim and
  AMRISim serve ARCOS on port 8101; ``tcp://host:port`` is taken as the same),
  ``rfc2217://host:port`` (a serial port shared over the network), ``spy://PORT`` (log
  the traffic), ``hwgrep://VID:PID`` (find a USB adapter by its IDs), ``loop://``;
- a path to a regular file of recorded bytes: read as fast as possible, then EOF.

Every transport has ``read(max_bytes, timeout_s) -> bytes`` (empty on timeout),
``write(data)``, ``close()``, ``eof`` (a file ran out) and ``fileno()`` (the descriptor
to wait on with a selector: a device path's; None for URLs and files). Opening failures raise
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

    def fileno(self) -> int | None:
        """The descriptor that becomes readable when ``read`` has bytes, if there is one
        (a device path); None for a pyserial URL or a file (read them with a timeout)."""
        return None

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialTransport(Transport):
    """A port opened with pyserial's ``serial_for_url``: a device path (read with select
    on its file descriptor, in blocks), or any pyserial URL (``socket://``, ``rfc2217://``,
    ``spy://``, ``hwgrep://``, ``loop://``: read through pyserial, so a ``spy://`` port
    logs what passes)."""

    def __init__(self, url: str, baud: int, shown: str | None = None) -> None:
        self.url = shown or url  # what the user wrote (tcp:// for socket://)
        self._fast = "://" not in url  # a device path: select + os.read on its fd
        try:
            self._port = serial.serial_for_url(url, baudrate=baud, timeout=0, write_timeout=2.0)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise _open_error(self.url, exc) from None
        sock = getattr(self._port, "_socket", None)
        if isinstance(sock, socket.socket):  # socket://, rfc2217://: no Nagle delay
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        try:
            if not self._fast:
                return self._read_url(max_bytes, timeout_s)
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

    def fileno(self) -> int | None:
        if not self._fast:
            return None
        try:
            return int(self._port.fileno())
        except (OSError, ValueError, serial.SerialException):
            return None

    def _read_url(self, max_bytes: int, timeout_s: float) -> bytes:
        """One byte with the timeout, then whatever else is there at once."""
        self._port.timeout = max(0.0, timeout_s)
        first = self._port.read(1)
        if not first:
            return b""
        self._port.timeout = 0
        return first + self._port.read(max_bytes - 1)

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
    if "://" in path and not path.startswith("file://"):
        return _url_error(path, text)
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


def _url_error(url: str, text: str) -> DeviceError:
    if url.startswith("hwgrep://"):
        return DeviceError(
            f"{url}: no serial port matches; list the ports with `hilnav probe --list`"
        )
    if url.startswith(("socket://", "rfc2217://", "tcp://")):
        why = text.split("] ", 1)[-1] if "] " in text else text
        return DeviceError(
            f"{url}: cannot connect ({why}); is the simulator or serial-to-TCP bridge "
            "running and listening on that port?"
        )
    return DeviceError(f"{url}: cannot open: {text}")


def open_transport(url: str, baud: int = 9600) -> Transport:
    """Open a device link by URL (see the module docstring)."""
    shown = url
    if url.startswith("tcp://"):  # the simulators' habit: the same as pyserial's socket://
        host, _, port = url[len("tcp://") :].rpartition(":")
        if not host or not port.isdigit():
            raise DeviceError(f"{url}: expected tcp://HOST:PORT, e.g. tcp://127.0.0.1:8101")
        url = f"socket://{host}:{port}"
    if "://" in url and not url.startswith("file://"):
        return SerialTransport(url, baud, shown)
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
