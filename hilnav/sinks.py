"""Where the daemon's messages go besides the bus: its MCAP log and the live view.

:class:`Sinks` encodes each message once (:class:`hilnav.log.encoding.Encoder`: the
native record and its Foxglove views; the daemon also sends the native record's bytes on
the bus) and hands the records to every sink by place name:
``log`` (:class:`hilnav.log.writer.LogWriter`) and ``live``
(:class:`hilnav.live.LiveBridge`, ``hilnav run --foxglove``). A sink that refuses a
message is reported to ``on_fault`` under its place and the others still get it.
:func:`open_run_log` opens a run's log with its metadata record.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilnav.config import RobotConfig
from hilnav.log.encoding import Encoder, Record, Sink, ViewMemo, stamp_of
from hilnav.log.writer import LogWriter


class Sinks:
    """The sinks of one daemon by place; ``write`` encodes once and writes to each."""

    def __init__(
        self,
        sinks: dict[str, Sink],
        on_fault: Callable[[str, BaseException], None],
        memo: ViewMemo | None = None,
    ) -> None:
        """``memo``: views shared with other robots' sinks in this process (a fleet host)."""
        self.sinks = dict(sinks)
        self._on_fault = on_fault
        self._encoder = Encoder(memo=memo)

    def __bool__(self) -> bool:
        return bool(self.sinks)

    def add(self, place: str, sink: Sink) -> None:
        self.sinks[place] = sink

    def write(self, topic: str, msg: Any, log_ns: int) -> bool:
        """Log time ``log_ns``, publish time the message's stamp; True if every sink took it."""
        records = self.encode(topic, msg)
        return records is not None and self.write_records(records, log_ns, stamp_of(msg))

    def encode(self, topic: str, msg: Any) -> list[Record] | None:
        """The message's records (the native one first), or None if it cannot be encoded
        (reported to ``on_fault`` as "log")."""
        try:
            return self._encoder.encode(topic, msg)
        except Exception as exc:
            self._on_fault("log", exc)
            return None

    @property
    def splits(self) -> bool:
        """Whether :meth:`encode_native` then :meth:`views` may stand for :meth:`encode`."""
        return self._encoder.splits

    def encode_native(self, topic: str, msg: Any) -> Record | None:
        """The native record alone, or None (reported as :meth:`encode` does)."""
        try:
            return self._encoder.native(topic, msg)
        except Exception as exc:
            self._on_fault("log", exc)
            return None

    def views(self, topic: str, msg: Any) -> list[Record]:
        """The message's Foxglove views, after its native record (:meth:`encode_native`)."""
        return self._encoder.views_of(topic, msg)

    def write_records(self, records: list[Record], log_ns: int, publish_ns: int | None) -> bool:
        """Records of one message to every sink; True if every sink took them."""
        ok = True
        for place, sink in self.sinks.items():
            try:
                sink.write_records(records, log_ns, publish_ns)
            except Exception as exc:
                self._on_fault(place, exc)
                ok = False
        return ok

    def close(self) -> None:
        for sink in self.sinks.values():
            with contextlib.suppress(Exception):
                sink.close()


def default_log_path(cfg: RobotConfig) -> Path:
    """``[log] dir/<robot>-<UTC time>.mcap``."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    return Path(cfg.log.dir) / f"{cfg.name}-{stamp}.mcap"


def open_run_log(
    cfg: RobotConfig, path: Path, *, simulated: bool, services: list[str]
) -> LogWriter:
    """The run's MCAP log, its metadata record holding the robot, the config (and the
    config file's text, for ``hilnav replay``), the simulation and the services. OSError
    when the file cannot be written."""
    meta = {
        "robot": cfg.name,
        "config": cfg.source,
        "simulated": str(simulated).lower(),
        "plan": cfg.simulation.plan if simulated else "",
        "seed": str(cfg.simulation.seed) if simulated else "",
        "services": ",".join(services),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    src = Path(cfg.source)
    if cfg.source != "<defaults>" and src.is_file():
        meta["config_toml"] = src.read_text(encoding="utf-8")
    return LogWriter(path, compression=cfg.log.compression, metadata=meta)
