"""hilnav's IR ADC board (Sharp GP2Y0A710K0F sensors): serial and CAN protocol, conversion.

The protocol is defined in docs/protocols/irboard.md.
"""

from drivers.irboard.canframe import (
    COMMAND_ID_BASE,
    SAMPLE_ID_BASE,
    CanSampleDecoder,
    pack_sample,
    pack_set_rate,
    unpack_command,
    unpack_sample,
)
from drivers.irboard.codec import IrCanCodec, IrSerialCodec
from drivers.irboard.convert import PAPER_MOUNTS, IrBoardConfig, IrConverter, volts_to_counts
from drivers.irboard.serialframe import (
    BoardCommand,
    RawSample,
    SerialFrameDecoder,
    crc16_ccitt,
    encode_command,
    encode_sample,
    set_rate_command,
)

__all__ = [
    "COMMAND_ID_BASE",
    "PAPER_MOUNTS",
    "SAMPLE_ID_BASE",
    "BoardCommand",
    "CanSampleDecoder",
    "IrBoardConfig",
    "IrCanCodec",
    "IrConverter",
    "IrSerialCodec",
    "RawSample",
    "SerialFrameDecoder",
    "crc16_ccitt",
    "encode_command",
    "encode_sample",
    "pack_sample",
    "pack_set_rate",
    "set_rate_command",
    "unpack_command",
    "unpack_sample",
    "volts_to_counts",
]
