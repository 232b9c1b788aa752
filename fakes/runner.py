"""Runs the emulated devices of one process around one simulated world.

The runner steps the world in real time at a fixed period in its own thread; before
every step it calls each emulator's ``tick(dt)`` with the world locked, so emulators
turn commands into wheel speeds and sample the truth consistently. Emulators do their
own I/O in their own threads and take ``runner.lock`` when they touch the world.
"""

from __future__ import annotations

import tempfile
import threading
import time
from pathlib import Path
from typing import Protocol

from fakes.world import World


class Emulator(Protocol):
    name: str

    def start(self, runner: FakeRunner) -> None: ...

    def tick(self, dt: float) -> None: ...

    def stop(self) -> None: ...

    def ports(self) -> dict[str, str]: ...


class FakeRunner:
    """Owns the world, its clock thread and the emulators; ``ports()`` maps names to paths."""

    def __init__(
        self, world: World, period_s: float = 0.01, link_dir: str | Path | None = None
    ) -> None:
        self.world = world
        self.period_s = period_s
        self.lock = threading.RLock()
        self.emulators: list[Emulator] = []
        self._tmp = None
        if link_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="hilnav-fake-")
            link_dir = self._tmp.name
        self.link_dir = Path(link_dir)
        self.link_dir.mkdir(parents=True, exist_ok=True)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def add(self, emulator: Emulator) -> Emulator:
        self.emulators.append(emulator)
        return emulator

    def start(self) -> None:
        for e in self.emulators:
            e.start(self)
        self._thread = threading.Thread(target=self._run, name="world", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            with self.lock:
                for e in self.emulators:
                    e.tick(self.period_s)
                self.world.step(self.period_s)
            next_t += self.period_s
            delay = next_t - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            elif delay < -1.0:
                next_t = time.monotonic()  # fell far behind (machine stalled): don't sprint

    def ports(self) -> dict[str, str]:
        out: dict[str, str] = {}
        for e in self.emulators:
            out.update(e.ports())
        return out

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for e in self.emulators:
            e.stop()
        if self._tmp is not None:
            self._tmp.cleanup()

    def __enter__(self) -> FakeRunner:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
