"""MCAP log writer: every message as hilnav JSON, plus Foxglove views, crash-safe.

One channel per (topic, schema). What a message becomes comes from
:class:`hilnav.log.encoding.Encoder`: the native record on its topic with schema
``msgs.schema_name(cls)`` (``hilnav.<Class>``, JSON Schema from ``msgs.json_schema``; the
map, a Foxglove message itself, gets Foxglove's official schema) and JSON encoding
(``msgs.encode``), and where a Foxglove schema fits a view on its own
channel, so the Foxglove app draws the log with no plugin. The live bridge
(:mod:`hilnav.live`) serves the same records; :meth:`LogWriter.write_records` takes
records encoded once for both.

The file itself is written by :class:`hilnav.log.mcap_file.McapFile`: the bytes the mcap
library's writer would write, with the messages packed by hand (four times faster).

Crash safety: the open chunk is kept in memory until it reaches ``chunk_size``. Here the
chunk is finished and written out (``McapFile.flush``) whenever
``flush_every_s`` of log time has passed since the chunk's first message and, unless
``wall_clock=False``, also by a timer thread every ``flush_every_s`` of wall time, which
also fsyncs what was written (``fsync=True``) so that a power cut loses no more. A killed
process therefore loses at most about ``flush_every_s`` of messages; ``hilnav log recover``
turns the truncated file back into a valid one. With ``wall_clock=False`` the chunk
boundaries depend only on the messages, so the same input gives the same bytes (replay).

Thread-safe: one lock around every call.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from hilnav.log.encoding import Encoder, Record, dumps
from hilnav.log.mcap_file import COMPRESSIONS, McapFile
from hilnav.osthread import NamedThread

METADATA_NAME = "hilnav"
PROFILE = ""
LIBRARY = "hilnav"
_U64 = 2**64


def _times(topic: str, log_time_ns: int, publish_time_ns: int | None) -> tuple[int, int]:
    """(log, publish) times as ints; publish defaults to log; ValueError if not a uint64."""
    log_ns = int(log_time_ns)
    pub_ns = log_ns if publish_time_ns is None else int(publish_time_ns)
    if not (0 <= log_ns < _U64 and 0 <= pub_ns < _U64):
        raise ValueError(f"{topic}: log/publish time {log_ns}/{pub_ns} is not a uint64")
    return log_ns, pub_ns


class LogWriter:
    """Write hilnav messages to one MCAP file (context manager).

    ``write(topic, msg, log_time_ns, publish_time_ns=None)`` logs ``msg`` on ``topic`` (an
    MCAP topic such as ``/r1/pose``) and its Foxglove views. ``metadata`` (str -> str) is
    written as the MCAP metadata record "hilnav" (robot, plan, seed, config ...).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        compression: str = "zstd",
        flush_every_s: float = 1.0,
        chunk_size: int = 1024 * 1024,
        metadata: dict[str, str] | None = None,
        foxglove_views: bool = True,
        wall_clock: bool = True,
        fsync: bool = True,
    ) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(
                f"compression {compression!r}: choose one of {', '.join(COMPRESSIONS)}"
            )
        if flush_every_s <= 0:
            raise ValueError("flush_every_s must be > 0")
        self.path = Path(path)
        self._flush_ns = int(flush_every_s * 1e9)
        self._flush_s = float(flush_every_s)
        self._encoder = Encoder(views=foxglove_views)
        self._lock = threading.Lock()
        self._stream = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = McapFile(self._stream, chunk_size=chunk_size, compression=compression)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        # (topic, schema name, message encoding) -> [channel id, next sequence number]
        self._channels: dict[tuple[str, str, str], list[int]] = {}
        self._pending = 0  # messages in the open chunk
        self._chunk_first_ns: int | None = None
        self._last_flush_wall = time.monotonic()
        self._closed = False
        self._dirty = False  # chunks handed to the OS since the last fsync
        # fsync (power loss, not only a killed process) from the timer thread, outside the
        # lock, on a duplicate descriptor that close() cannot pull away under it.
        self._sync_fd = os.dup(self._stream.fileno()) if fsync and wall_clock else None
        self.messages_written = 0
        self.bytes_written = 0
        if metadata:
            self.add_metadata(METADATA_NAME, metadata)
        self._stream.flush()
        self._stop = threading.Event()
        self._timer: threading.Thread | None = None
        if wall_clock:
            self._timer = NamedThread(target=self._tick, name="mcap-flush", daemon=True)
            self._timer.start()

    @property
    def views_skipped(self) -> int:
        """Views not written (odd messages, non-finite values)."""
        return self._encoder.views_skipped

    # -- context manager ---------------------------------------------------------------
    def __enter__(self) -> LogWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- registration ------------------------------------------------------------------
    def _schema_id(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding, data)
        sid = self._schemas.get(key)
        if sid is None:
            sid = self._writer.register_schema(name=name, encoding=encoding, data=data)
            self._schemas[key] = sid
        return sid

    def _channel_id(
        self,
        topic: str,
        schema_name: str,
        schema: dict[str, Any] | bytes | None,
        schema_encoding: str = "jsonschema",
        message_encoding: str = "json",
    ) -> list[int]:
        """[channel id, next sequence number] of the channel, registered on first use."""
        key = (topic, schema_name, message_encoding)
        channel = self._channels.get(key)
        if channel is None:
            if isinstance(schema, dict):
                data, enc = dumps(schema), schema_encoding
            elif isinstance(schema, bytes | bytearray) and schema:
                data, enc = bytes(schema), schema_encoding
            else:
                data, enc = b"", ""
            sid = self._schema_id(schema_name, enc, data)
            cid = self._writer.register_channel(
                topic=topic, message_encoding=message_encoding, schema_id=sid
            )
            channel = self._channels[key] = [cid, 0]
        return channel

    # -- writing -------------------------------------------------------------------------
    def _add(self, channel: list[int], data: bytes, log_ns: int, pub_ns: int) -> None:
        seq = channel[1]
        channel[1] = seq + 1
        first = self._chunk_first_ns
        if first is None:
            self._chunk_first_ns = log_ns
        elif abs(log_ns - first) >= self._flush_ns:
            self._flush_locked()
            self._chunk_first_ns = log_ns
        self._writer.add_message(channel[0], log_ns, data, pub_ns, seq)
        self._pending += 1
        self.messages_written += 1
        self.bytes_written += len(data)

    def write(
        self,
        topic: str,
        msg: Any,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        native: bytes | None = None,
    ) -> None:
        """Log ``msg`` (a msgs dataclass) on ``topic`` and its Foxglove views. ``native``:
        the bytes it was decoded from (a replayed log's record), logged as they are."""
        log_ns, pub_ns = _times(topic, log_time_ns, publish_time_ns)  # refused before encoding
        self.write_records(self._encoder.encode(topic, msg, native), log_ns, pub_ns)

    def write_records(
        self, records: Sequence[Record], log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Log the records of one message (:meth:`hilnav.log.encoding.Encoder.encode`)."""
        if not records:
            return
        log_ns, pub_ns = _times(records[0].topic, log_time_ns, publish_time_ns)
        channels = self._channels
        with self._lock:
            self._check_open()
            for r in records:
                channel = channels.get((r.topic, r.schema_name, "json"))
                if channel is None:
                    channel = self._channel_id(r.topic, r.schema_name, r.schema())
                self._add(channel, r.data, log_ns, pub_ns)

    def write_encoded(
        self,
        topic: str,
        schema_name: str,
        schema: dict[str, Any] | bytes | None,
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        schema_encoding: str = "jsonschema",
        message_encoding: str = "json",
    ) -> None:
        """Log an already encoded payload (pass-through of records we do not decode).

        ``schema`` is a JSON Schema (dict), the schema record's bytes (with
        ``schema_encoding``), or None for a schema-less channel."""
        log_ns, pub_ns = _times(topic, log_time_ns, publish_time_ns)
        with self._lock:
            self._check_open()
            channel = self._channel_id(
                topic, schema_name, schema, schema_encoding, message_encoding
            )
            self._add(channel, bytes(data), log_ns, pub_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """An MCAP metadata record (written at once, outside the chunks)."""
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})
            self._stream.flush()

    # -- flushing and closing -----------------------------------------------------------
    def _flush_locked(self) -> None:
        if self._pending:
            self._writer.flush()
            self._pending = 0
            self._dirty = True
        self._chunk_first_ns = None
        self._last_flush_wall = time.monotonic()

    def flush(self) -> None:
        """Finish the open chunk and hand everything to the OS now."""
        with self._lock:
            if not self._closed:
                self._flush_locked()

    def _tick(self) -> None:
        """Flush the open chunk once ``flush_every_s`` x 0.75 of wall time passed since the
        last flush (the writer's own log-time flushes count), fsync what was flushed;
        asleep in between (no polling)."""
        wait = self._flush_s * 0.75
        while not self._stop.wait(max(wait, 0.01)):
            with self._lock:
                if self._closed:
                    return
                since = time.monotonic() - self._last_flush_wall
                if self._pending and since >= self._flush_s * 0.75:
                    self._flush_locked()
                    since = 0.0
                dirty, self._dirty = self._dirty, False
            wait = self._flush_s * 0.75 - (since if self._pending else 0.0)
            if dirty:
                self._sync()

    def _sync(self) -> None:
        if self._sync_fd is not None:
            try:
                os.fsync(self._sync_fd)
            except OSError:  # e.g. a pipe or a file system without fsync: best effort
                pass

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"log {self.path} is closed")

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file. Idempotent."""
        self._stop.set()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()
            self._stream.close()
        if self._timer is not None and self._timer is not threading.current_thread():
            self._timer.join(timeout=2.0)
        if self._sync_fd is not None:
            self._sync()
            os.close(self._sync_fd)
            self._sync_fd = None
