"""What replay knows of the devices: their topics, and their codecs for raw bytes.

- the topic table: which device message is logged on which topic (as the daemon does),
  which topics feed the services, and which are the services' outputs;
- :func:`build_codecs`: the drivers' codecs, one per device, built from the robot config;
  :class:`RawDecoders` feeds them the logged raw bytes (:func:`decode_can_frame` for the
  IR board on CAN, whose driver logs each frame as arbitration id + data).
"""

from __future__ import annotations

from typing import Any

from msgs import GpsFix, GyroSample, IrScan, RawBytes, RobotInfo, RobotOdometry

# Device messages and the topics they are logged on (as the daemon does).
DEVICE_TOPICS: dict[type, str] = {
    RobotOdometry: "odometry",
    GyroSample: "gyro",
    GpsFix: "gps",
    IrScan: "ir",
    RobotInfo: "info",
}
INPUT_TOPICS = ("odometry", "gyro", "gps", "ir", "control", "landmark_scan")
# What the services produce: dropped from the input, produced again by the pipeline.
OUTPUT_TOPICS = frozenset(
    {"heading", "pose", "pose_box", "map", "association", "landmarks", "slam_pose"}
)


def build_codecs(config: Any) -> tuple[dict[str, Any], bool]:
    """The drivers' codecs by device name, and whether the IR board is on CAN."""
    from drivers.arcos.codec import ArcosCodec
    from drivers.cruzcore import CruzCoreCodec
    from drivers.irboard.codec import IrCanCodec, IrSerialCodec
    from drivers.nmea.codec import NmeaCodec
    from drivers.nmea.local import Datum
    from hilnav.config import ir_board_config

    d = config.devices
    ir = d.ir
    board = ir_board_config(config)
    ir_can = ir.link == "can"
    codecs: dict[str, Any] = {
        "arcos": ArcosCodec(),
        "gyro": CruzCoreCodec(),
        "gps": NmeaCodec(datum=Datum(*d.gps.datum)),
        "ir": IrCanCodec(board) if ir_can else IrSerialCodec(board),
    }
    return codecs, ir_can


def decode_can_frame(codec: Any, raw: RawBytes) -> list[Any]:
    """The IR scan (if one completes) of one logged CAN frame."""
    # The CAN driver logs each frame as 4 bytes of arbitration id + the data.
    if len(raw.data) < 4:
        return []
    arb = int.from_bytes(raw.data[:4], "big")
    scan = codec.feed_frame(arb, raw.data[4:], raw.stamp_ns, is_extended=arb > 0x7FF)
    return [] if scan is None else [scan]


class RawDecoders:
    """The drivers' codecs, one per device, rebuilding device messages from raw bytes."""

    def __init__(self, config: Any) -> None:
        self.codecs, self.ir_can = build_codecs(config)

    def feed(self, raw: RawBytes) -> list[Any]:
        if raw.direction != "rx":
            return []
        codec = self.codecs.get(raw.device)
        if codec is None:
            return []
        if raw.device == "ir" and self.ir_can:
            return decode_can_frame(codec, raw)
        return [m for m in codec.feed(raw.data, raw.stamp_ns) if type(m) in DEVICE_TOPICS]
