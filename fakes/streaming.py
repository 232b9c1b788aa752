"""Base of the emulated streaming sensors on a virtual serial port (IR board, gyro, GPS).

The runner calls ``tick(dt)`` with the world locked: the emulator samples the truth and
writes its frames at once. Writes never block: when nobody reads the port and the pty's
buffer is full, bytes are lost, as on a real UART. A thread reads what the driver sends
and hands it to ``on_input`` (commands).
"""

from __future__ import annotations

import contextlib
import threading

from fakes.pty import VirtualSerialPort


class PortEmulator:
    """An emulated device on one virtual serial port, served by a thread of its own."""

    name = "port"

    def __init__(self, name: str) -> None:
        self.name = name
        self.port: VirtualSerialPort | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _open(self, runner, baud: int | None = None, prefix: str = "fake") -> None:
        """Create the port under the runner's link directory and start serving it."""
        self.port = VirtualSerialPort(runner.link_dir / self.name, baud=baud)
        self._on_port(self.port)
        self._thread = threading.Thread(
            target=self._serve, name=f"{prefix}-{self.name}", daemon=True
        )
        self._thread.start()

    def _on_port(self, port: VirtualSerialPort) -> None:
        """Set the new port up before its thread starts (subclasses)."""

    def _serve(self) -> None:
        """The port's thread (subclasses)."""

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self.port is not None:
            self.port.close()

    def ports(self) -> dict[str, str]:
        return {self.name: self.port.path} if self.port else {}


class PtyStreamEmulator(PortEmulator):
    name = "stream"

    def __init__(self, name: str, robot: str = "r1") -> None:
        super().__init__(name)
        self.robot_name = robot
        self._runner = None
        self.bytes_dropped = 0
        self.lock = threading.Lock()

    def start(self, runner) -> None:
        self._runner = runner
        self._open(runner)

    def send(self, data: bytes) -> None:
        """Non-blocking write; what does not fit in the pty buffer is lost."""
        if self.port is not None:
            self.bytes_dropped += self.port.write(data, block=False)

    def _serve(self) -> None:
        while not self._stop.is_set():
            port = self.port
            if port is None:
                return
            data = port.read(0.05)
            if data:
                with contextlib.suppress(Exception):
                    self.on_input(data)

    def on_input(self, data: bytes) -> None:
        """Bytes written by the driver (subclasses parse commands)."""

    def tick(self, dt: float) -> None:
        """Sample the world (called with the world locked)."""
