"""The services of one robot wired together: device messages in, estimates and maps out.

``Pipeline(config).feed(topic, msg)`` takes one message of a service-input topic
(:data:`hilnav.topics.SERVICE_INPUTS`; others are ignored) and returns the
``(topic, msg)`` outputs it caused, in a fixed order: heading, pose, pose_box,
association, map. Time is the messages' stamps and randomness is seeded: the same inputs
in the same order give the same outputs, which is what ``hilnav replay`` relies on. Each
service is switched on or off by ``[services.*].enabled``.

Wiring (see hilnav.services for each adapter):

    odometry, gyro ------> heading ---> mapping (with each ir scan) ---> map, association
    odometry, gyro, gps -> pose (frame "map")
    odometry, gyro, gps -> localization (CP) ---> pose_box (+ the fleet's pose boxes)

On a robot the mapping service runs in a :class:`MappingWorker` thread the pipeline owns
(``Pipeline(cfg, on_mapping=...)``), fed the same inputs in the same order, so a slow
data-association step never delays the pose; its outputs go to ``on_mapping(topic, msg,
tag)`` with the ``tag`` of the input that caused them (the daemon's receive time). With
``on_output`` every other output is also handed to ``on_output(topic, msg, tag)`` the
moment its service made it, before the next service runs: the daemon publishes the pose
before CP localization starts its step.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import Any

from hilnav.config import RobotConfig
from hilnav.osthread import NamedThread
from hilnav.services import HeadingAdapter, LocalizationAdapter, MappingAdapter, PoseAdapter
from hilnav.topics import SERVICE_INPUTS

Outputs = list[tuple[str, Any]]
MappingSink = Callable[[str, Any, Any], None]
FaultSink = Callable[[str, BaseException], None]


class MappingWorker:
    """The mapping service in its own thread: inputs queued in order, outputs to a sink.

    The thread takes its inputs in batches: it wakes every ``batch_s`` (or when
    ``batch_max`` inputs wait) and handles all that came, in order, instead of being woken
    by each of the 30 inputs a second (IR scans, headings). A put is then a list append
    (no futex, no hand-over of the GIL to the mapping thread in the middle of the device
    loop's turn); the map is at most ``batch_s`` later, and the same."""

    def __init__(
        self,
        mapping: MappingAdapter,
        sink: MappingSink,
        on_fault: FaultSink,
        latest: dict[str, Any],
        queue_size: int = 20000,
        batch_s: float = 0.1,
        batch_max: int = 64,
    ) -> None:
        self.mapping = mapping
        self.sink = sink
        self.on_fault = on_fault
        self.latest = latest
        self.dropped = 0
        self.batches = 0  # wake-ups that found inputs
        self.batch_s = batch_s
        self._q: collections.deque[tuple[str, Any, Any]] = collections.deque()
        self._queue_size = queue_size
        self._batch_max = batch_max
        self._wake = threading.Event()
        self._thread = NamedThread(target=self._loop, name="mapping", daemon=True)
        self._thread.start()

    def put(self, topic: str, msg: Any, tag: Any) -> None:
        q = self._q
        if len(q) >= self._queue_size:
            self.dropped += 1
            return
        q.append((topic, msg, tag))  # (deque.append is atomic)
        if len(q) >= self._batch_max:
            self._wake.set()

    def _loop(self) -> None:
        q, wake = self._q, self._wake
        while True:
            wake.wait(self.batch_s)
            wake.clear()
            if q:
                self.batches += 1
            while q:
                topic, msg, tag = q.popleft()
                if msg is None:
                    return
                self._handle(topic, msg, tag)

    def _handle(self, topic: str, msg: Any, tag: Any) -> None:
        try:
            outs = self.mapping.feed(topic, msg)
        except Exception as exc:
            self.on_fault("mapping", exc)
            return
        for t, m in outs:
            self.latest[t] = m
            try:
                self.sink(t, m, tag)
            except Exception as exc:
                self.on_fault("mapping", exc)

    def close(self, timeout_s: float = 10.0) -> None:
        """Finish what is queued, then stop the thread."""
        self._q.append(("", None, None))
        self._wake.set()
        self._thread.join(timeout_s)

    @property
    def done(self) -> bool:
        """The thread has stopped (after :meth:`close`): the mapping is no longer fed."""
        return not self._thread.is_alive()


class Pipeline:
    """Deterministic service graph of one robot (see the module docstring)."""

    def __init__(
        self,
        config: RobotConfig,
        on_mapping: MappingSink | None = None,
        on_fault: FaultSink | None = None,
        on_output: MappingSink | None = None,
    ) -> None:
        self.config = config
        self.on_output = on_output
        sv = config.services
        self.heading = HeadingAdapter(config) if sv.heading.enabled else None
        self.pose = PoseAdapter(config) if sv.pose.enabled else None
        self.localization = LocalizationAdapter(config) if sv.localization.enabled else None
        self.mapping = MappingAdapter(config) if sv.mapping.enabled else None
        self.latest: dict[str, Any] = {}
        self.worker: MappingWorker | None = None
        if self.mapping is not None and on_mapping is not None:
            self.worker = MappingWorker(self.mapping, on_mapping, on_fault or _ignore, self.latest)

    @property
    def services(self) -> list[str]:
        """Names of the services that run."""
        names = ("heading", "pose", "localization", "mapping")
        return [n for n in names if getattr(self, n) is not None]

    def feed(self, topic: str, msg: Any, tag: Any = None) -> Outputs:
        """Outputs caused by one input message (none for topics the services ignore);
        with a mapping worker, the mapping's outputs come later, through its sink."""
        if topic not in SERVICE_INPUTS:
            return []
        out: Outputs = []
        for service in (self.heading, self.pose, self.localization):
            if service is not None:
                self._take(service.feed(topic, msg), out, tag)
        if self.mapping is not None:
            for t, m in [*out, (topic, msg)]:
                if t in ("heading", "ir"):
                    if self.worker is not None:
                        self.worker.put(t, m, tag)
                    else:
                        self._take(self.mapping.feed(t, m), out, tag)
        return out

    def _take(self, outputs: Outputs, out: Outputs, tag: Any) -> None:
        emit = self.on_output
        for t, m in outputs:
            self.latest[t] = m
            out.append((t, m))
            if emit is not None:
                emit(t, m, tag)

    def feed_other(self, robot: str, topic: str, msg: Any) -> Outputs:
        """Messages of other fleet robots (cooperative localization: their pose boxes)."""
        if self.localization is not None:
            return self.localization.feed_other(robot, topic, msg)
        return []

    def drop_peer(self, robot: str) -> None:
        """A peer left (or went silent): forget its box."""
        if self.localization is not None:
            self.localization.drop_peer(robot)

    def close(self) -> None:
        """Let the mapping worker finish its queue (no-op without one)."""
        if self.worker is not None:
            self.worker.close()

    def finish(self) -> Outputs:
        """The services' last outputs at the end of a run, after :meth:`close` (the
        mapping's final map, its pose graph solved: :meth:`MappingAdapter.finish`)."""
        if self.mapping is None or (self.worker is not None and not self.worker.done):
            return []  # (a worker still busy after close()'s wait: its map stays as it is)
        out: Outputs = []
        self._take(self.mapping.finish(), out, None)
        return out


def _ignore(where: str, exc: BaseException) -> None:
    return None
