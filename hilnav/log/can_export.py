"""A log's raw CAN frames as a python-can log file (.asc, .blf, .csv, .log, .trc, ...).

The daemon logs every frame of a device on CAN as one msgs.RawBytes record
(:func:`drivers.irboard.canframe.pack_raw_frame`: arbitration id with the SocketCAN EFF
flag, then the data). :func:`export_can` turns those records back into ``can.Message``
objects and hands them to python-can's own ``can.Logger``, which picks the format from
the file's extension; ``can.LogReader`` and ``can.player`` read the result.
"""

from __future__ import annotations

from pathlib import Path

import can

from drivers.irboard.canframe import unpack_raw_frame
from hilnav.log.reader import read_messages
from hilnav.topics import raw_topic, split_log_topic
from msgs import RawBytes


def export_can(log: str | Path, out: str | Path, device: str = "ir", channel: str = "") -> int:
    """Write the CAN frames of ``device`` (every robot in the log) to ``out``; returns how
    many. Records too short to be a frame are skipped."""
    n = 0
    logger = can.Logger(str(out))
    try:
        for m in read_messages(log):
            robot, name = split_log_topic(m.topic)
            if name != raw_topic(device) or not isinstance(m.msg, RawBytes):
                continue
            frame = unpack_raw_frame(m.msg.data)
            if frame is None or m.msg.direction != "rx":
                continue
            arb, data, ext = frame
            logger.on_message_received(
                can.Message(
                    timestamp=m.msg.stamp_ns * 1e-9,
                    arbitration_id=arb,
                    is_extended_id=ext,
                    data=data,
                    channel=channel or robot,
                    is_rx=True,
                )
            )
            n += 1
    finally:
        logger.stop()
    return n
