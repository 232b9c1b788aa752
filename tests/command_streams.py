"""Clean command streams of the fakes' parsers, for the fuzzer (tests/codec_fuzz.py).

The emulated IR board decodes SET_RATE and other command frames with the serial framing's
command decoder; the emulated gyro splits ``$MIA``/``$MIB`` lines with
:class:`drivers.cruzcore.CommandParser`. Neither is a driver's codec, but a command lost
there (split across reads, or without its line end) changes what the fake does.
"""

from __future__ import annotations

import random

from drivers.cruzcore import (
    CommandParser,
    command,
    config_command,
    reset_command,
    sum_checksum,
)
from drivers.irboard.serialframe import SYNC_CMD, SerialFrameDecoder, encode_command
from tests.codec_fuzz import Key, Stream, random_bytes


class IrCommands(Stream):
    name = "ir_command"
    sync = SYNC_CMD
    special = b"\xa5\xc3\x01\x10"

    def __init__(self) -> None:
        frames = [encode_command(k % 4, 1 + k % 3, bytes(range(k, k + 5 * k % 17)))
                  for k in range(10)]  # fmt: skip
        self.frames = self._keyed(frames)

    def new(self) -> SerialFrameDecoder:
        return SerialFrameDecoder(commands=True)

    def feed(self, codec: SerialFrameDecoder, chunk: bytes, stamp: int) -> list[Key]:
        return [(c.board_id, c.cmd, c.payload) for c in codec.feed(chunk)]

    def lengths(self, data: bytes, p: int) -> list[int]:
        return [7 + data[p + 4]] if p + 4 < len(data) else []

    def valid(self, raw: bytes) -> bool:
        ok = len(raw) >= 7 and raw[:2] == SYNC_CMD and raw[4] <= 16 and len(raw) == 7 + raw[4]
        return ok and encode_command(raw[2], raw[3], raw[5:-2]) == raw

    def field(self, raw: bytes, rng: random.Random) -> bytes:
        payload = random_bytes(rng, rng.choice((0, 2, 16, 17, rng.randint(0, 20))))
        return encode_command(rng.getrandbits(8), rng.getrandbits(8), payload)

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes:
        if rng.random() < 0.5:  # the payload length maxed, CRC left as it was
            return raw[:4] + b"\x10" + raw[5:]
        return encode_command(raw[2], raw[3], random_bytes(rng, 16))


class GyroCommands(Stream):
    name = "gyro_command"
    codec_type = CommandParser
    sync = b"$"
    special = b"$*,\r\nMIAB0123456789"

    def __init__(self) -> None:
        frames = [reset_command()] + [config_command(rate_hz=5 + 7 * k) for k in range(6)]
        frames += [config_command(9600 * (k + 1), 50 + k) for k in range(3)]
        self.frames = self._keyed(frames)

    def feed(self, codec: CommandParser, chunk: bytes, stamp: int) -> list[Key]:
        return list(codec.feed(chunk))

    def lengths(self, data: bytes, p: int) -> list[int]:
        lf, nxt = data.find(b"\n", p), data.find(b"$", p + 1)
        return [n for n in (lf - p + 1 if lf >= 0 else 0, nxt - p if nxt >= 0 else 0) if n]

    def valid(self, raw: bytes) -> bool:
        """``$body*hex`` of ASCII with the SUM of the body, as parse_command checks it."""
        text = raw.strip()
        body, star, hh = text[1:].rpartition(b"*")
        if not (text[:1] == b"$" and star and text.isascii()):
            return False
        try:
            return int(hh, 16) == sum_checksum(body.decode())
        except ValueError:
            return False

    def field(self, raw: bytes, rng: random.Random) -> bytes:
        parts = raw[1 : raw.rfind(b"*")].decode("ascii").split(",")
        values = ("", "RESET", "MIA", "MIB", "R", "B", "9999999999", "-1", "x", "0")
        parts[rng.randrange(len(parts))] = rng.choice(values)
        return command(",".join(parts))

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes:
        return command("MIA,,,,R,5," + "0" * rng.choice((60, 66, 67, 70)))


COMMAND_STREAMS: dict[str, type[Stream]] = {a.name: a for a in (IrCommands, GyroCommands)}
