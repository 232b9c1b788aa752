"""Device health counters, published at 1 Hz by the daemon for every device."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class DeviceDiagnostics:
    """Counters of one device link since the driver started.

    frames_ok / bad_checksums / resyncs / bytes_skipped come from the codec;
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
