"""Health counters published at 1 Hz by the daemon: one per device, one for itself."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class DeviceDiagnostics:
    """Counters of one device link since the driver started.

    frames_ok / bad_checksums / resyncs / bytes_skipped / frames_lost / malformed /
    duplicates come from the codec (drivers.base.CodecStats says what each counts);
    reconnects and last_error from the driver; last_seen_ns is the stamp of the last
    good frame (0 if none); rate_hz the good-frame rate over the last report period.
    """

    stamp_ns: int
    device: str
    connected: bool = False
    frames_ok: int = 0
    bad_checksums: int = 0
    resyncs: int = 0
    bytes_skipped: int = 0
    frames_lost: int = 0
    reconnects: int = 0
    last_seen_ns: int = 0
    rate_hz: float = 0.0
    last_error: str = ""
    malformed: int = 0
    duplicates: int = 0


@dataclass(frozen=True, slots=True)
class DaemonStatus:
    """Health of one daemon's own loop, bus and motion gate since it started.

    bus_*: Zenoh samples received, refused as malformed (bad JSON, types, ranges, size,
    nesting) or as foreign (not from the fleet), and callbacks that raised; queue_*:
    messages the service loop handled, and dropped because it fell behind; faults: the
    exceptions caught per place (services, log, bus, mapping, diagnostics, watchdog) and
    the last one; cmd_*: velocity commands obeyed, refused, and the stops made by the
    command timeout and by a stalled service loop; clock_*: the steps of the host's wall
    clock the stamps did not follow back, and followed forward (drivers.clock).
    """

    stamp_ns: int
    robot: str
    bus_received: int = 0
    bus_malformed: int = 0
    bus_foreign: int = 0
    bus_callback_errors: int = 0
    bus_last_problem: str = ""
    queue_processed: int = 0
    queue_dropped: int = 0
    faults: dict[str, int] = field(default_factory=dict)
    last_fault: str = ""
    cmd_received: int = 0
    cmd_rejected: int = 0
    cmd_timeouts: int = 0
    cmd_stalls: int = 0
    clock_back_steps: int = 0
    clock_forward_steps: int = 0
