"""Emulated NMEA GPS receivers: simulated from the world's truth, or replaying a log.

:class:`GpsEmulator` writes one epoch (GGA, GSA, RMC, VTG, GST, ZDA by default) every
1/rate seconds (1-10 Hz) with the robot's true position offset by the GPS error model
(white noise, a wandering Gauss-Markov bias, outages during which epochs carry no fix;
fakes.world.gps_model). The world's map frame is east/north metres about ``datum``.

:class:`NmeaReplayEmulator` serves a recorded NMEA log (gpsd's format: ``#`` comment lines
are skipped) on a pty, like gpsfake: at the log's own pace (epochs spaced by the time of
day in their sentences, 1 s when unknown) or as fast as the reader takes them. Like
gpsfake it waits for a reader before it starts: the pty's master is in packet mode, where
the reader's open (pyserial flushes its input when it opens a port) shows up as a
FLUSHREAD event; otherwise the first epochs would be thrown away by that flush.
"""

from __future__ import annotations

import datetime as dt
import fcntl
import math
import os
import select
import struct
import termios
import threading
import time
from pathlib import Path

from drivers.nmea.local import Datum
from drivers.nmea.sentences import time_of_day_ms
from drivers.nmea.writer import DEFAULT_TYPES, epoch_sentences
from fakes.pty import VirtualSerialPort
from fakes.streaming import PortEmulator, PtyStreamEmulator
from fakes.world.gps_model import GpsErrorModel
from msgs import GpsFix

DEFAULT_DATUM = Datum(37.5665, 126.9780)


class GpsEmulator(PtyStreamEmulator):
    def __init__(
        self,
        robot: str = "r1",
        rate_hz: float = 1.0,
        error: GpsErrorModel | None = None,
        datum: Datum = DEFAULT_DATUM,
        alt_m: float = 40.0,
        start_utc: dt.datetime | None = None,
        talker: str = "GP",
        types: tuple[str, ...] = DEFAULT_TYPES,
        name: str = "gps",
    ) -> None:
        super().__init__(name, robot)
        if not 1.0 <= rate_hz <= 10.0:
            raise ValueError(f"gps.rate_hz must be 1..10, not {rate_hz}")
        self.rate_hz = rate_hz
        self.error = error or GpsErrorModel()
        self.datum = datum
        self.alt_m = alt_m
        self.start_utc = start_utc
        self.talker = talker
        self.types = types
        self._due = 0.0
        self.epochs = 0

    def start(self, runner) -> None:
        if self.start_utc is None:
            now = dt.datetime.now(dt.UTC)
            self.start_utc = now.replace(microsecond=(now.microsecond // 100_000) * 100_000)
        super().start(runner)

    def tick(self, dt_s: float) -> None:
        if self._runner is None:
            return
        self._due += dt_s * self.rate_hz
        if self._due < 1.0:
            return
        self._due -= 1.0
        world = self._runner.world
        robot = world.robots[self.robot_name]
        err = self.error.sample(1.0 / self.rate_hz)
        assert self.start_utc is not None
        when = self.start_utc + dt.timedelta(microseconds=world.time_ns // 1000)
        when = when.replace(microsecond=(when.microsecond // 10_000) * 10_000)
        sigma = self.error.horizontal_sigma_m
        if err is None:
            fix = GpsFix(stamp_ns=world.time_ns, mode=1, satellites=3, hdop=99.0)
        else:
            lat, lon = self.datum.to_geodetic(robot.pose.x + err[0], robot.pose.y + err[1])
            course = (90.0 - math.degrees(robot.pose.theta)) % 360.0
            fix = GpsFix(
                stamp_ns=world.time_ns,
                lat_deg=lat,
                lon_deg=lon,
                alt_msl_m=self.alt_m + float(err[2]),
                geoid_sep_m=20.0,
                mode=3,
                quality=1,
                satellites=9,
                hdop=self.error.hdop,
                pdop=round(1.7 * self.error.hdop, 1),
                vdop=round(1.4 * self.error.hdop, 1),
                speed_mps=abs(robot.speed_mps),
                course_deg=course,
                std_lat_m=sigma,
                std_lon_m=sigma,
                std_alt_m=sigma * self.error.vertical_factor,
            )
        self.epochs += 1
        self.send(epoch_sentences(fix, when, self.talker, self.types))


def split_epochs(raw: bytes) -> list[bytes]:
    """A log's sentences grouped by epoch (a new time of day starts a new group)."""
    groups: list[list[bytes]] = []
    current_t: int | None = None
    for line in raw.splitlines(keepends=True):
        if line.startswith(b"#") or not line.strip():
            continue
        t = None
        parts = line.split(b",", 2)
        if len(parts) > 1 and parts[0][-3:] in (b"GGA", b"RMC", b"GLL", b"GST", b"ZDA"):
            field = parts[1] if parts[0][-3:] != b"GLL" else b""
            try:
                t = time_of_day_ms(field.decode("ascii"))
            except UnicodeDecodeError:
                t = None
        if not groups or (t is not None and current_t is not None and t != current_t):
            groups.append([])
        if t is not None:
            current_t = t
        if not line.endswith(b"\n"):
            line += b"\r\n"
        groups[-1].append(line)
    return [b"".join(g) for g in groups]


def _epoch_time(chunk: bytes) -> int | None:
    for line in chunk.splitlines():
        parts = line.split(b",", 2)
        if len(parts) > 1 and parts[0][-3:] in (b"GGA", b"RMC", b"GST", b"ZDA"):
            try:
                t = time_of_day_ms(parts[1].decode("ascii"))
            except UnicodeDecodeError:
                continue
            if t is not None:
                return t
    return None


class NmeaReplayEmulator(PortEmulator):
    """A recorded NMEA log on a pty (see the module docstring); not driven by the world."""

    def __init__(
        self,
        path: str | Path,
        name: str = "gps",
        fast: bool = False,
        loop: bool = False,
        wait_for_reader_s: float = 60.0,
    ) -> None:
        super().__init__(name)
        self.wait_for_reader_s = wait_for_reader_s
        self.path = Path(path)
        try:
            raw = self.path.read_bytes()
        except OSError as exc:
            raise ValueError(f"--replay gps={path}: cannot read the log ({exc.strerror})") from None
        self.epochs = split_epochs(raw)
        if not self.epochs:
            raise ValueError(f"--replay gps={path}: no NMEA sentences in the file")
        self.fast = fast
        self.loop = loop
        self.sent_epochs = 0
        self.done = threading.Event()

    def start(self, runner) -> None:
        self._open(runner, prefix="replay")

    def _on_port(self, port: VirtualSerialPort) -> None:
        assert port.master is not None
        fcntl.ioctl(port.master, termios.TIOCPKT, struct.pack("i", 1))

    def tick(self, dt: float) -> None:
        pass

    def _write_all(self, data: bytes) -> bool:
        """Blocking write that gives up when stopping (fast mode waits for the reader)."""
        port = self.port
        if port is None or port.master is None:
            return False
        return port.write(data, stop=self._stop) == 0 and not self._stop.is_set()

    def _wait_for_reader(self) -> None:
        """Until the reader opens the port (a FLUSHREAD packet-mode event) or time is up."""
        end = time.monotonic() + self.wait_for_reader_s
        while not self._stop.is_set() and (left := end - time.monotonic()) > 0:
            fd = self.port.master if self.port else None
            if fd is None:
                return
            ready, _, _ = select.select([fd], [], [], min(left, 0.1))
            if ready:
                try:
                    status = os.read(fd, 4096)
                except OSError:
                    return
                if status and status[0] & termios.TIOCPKT_FLUSHREAD:
                    self._stop.wait(0.05)  # let the reader finish its setup
                    return

    def _serve(self) -> None:
        self._wait_for_reader()
        while not self._stop.is_set():
            prev: int | None = None
            for chunk in self.epochs:
                if self._stop.is_set():
                    return
                t = _epoch_time(chunk)
                if not self.fast and self.sent_epochs:
                    gap = 1.0
                    if t is not None and prev is not None:
                        gap = ((t - prev) % 86_400_000) / 1000.0
                    self._stop.wait(min(max(gap, 0.0), 2.0))
                if t is not None:
                    prev = t
                if not self._write_all(chunk):
                    return
                self.sent_epochs += 1
            if not self.loop:
                self.done.set()
                return
