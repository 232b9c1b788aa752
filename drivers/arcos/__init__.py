"""Pioneer ARCOS protocol: framing, commands, server packets, codec and driver."""

from drivers.arcos.codec import ArcosCodec, OdometryTracker, unwrap15
from drivers.arcos.commands import Cmd, encode_command
from drivers.arcos.packet import ArcosPacket, PacketParser, checksum, frame
from drivers.arcos.params import P3DX, P3DX_SH, RobotParams, params_for

__all__ = [
    "P3DX",
    "P3DX_SH",
    "ArcosCodec",
    "ArcosPacket",
    "Cmd",
    "OdometryTracker",
    "PacketParser",
    "RobotParams",
    "checksum",
    "encode_command",
    "frame",
    "params_for",
    "unwrap15",
]
