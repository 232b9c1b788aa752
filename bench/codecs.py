"""Codec throughput: decode and encode rates per second. Prints JSON on its last line.

Each entry of BENCHES is a name -> function returning the units it processed. ARCOS SIPs
and commands; IR board frames (serial bytes and CAN frames, with conversion to ranges);
CruzCore gyro packets; NMEA sentences (framing, checksum, parsing, epoch combining) and,
on the same sentences, pynmea2's parser as the baseline (``nmea_vs_pynmea2`` = our rate
over pynmea2's; pynmea2 only parses, it neither frames a byte stream nor combines epochs).
"""

from __future__ import annotations

import datetime as dt
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from drivers.arcos import ArcosCodec, Cmd, encode_command, frame  # noqa: E402
from drivers.arcos.packets import encode_sip  # noqa: E402
from drivers.cruzcore import CruzCoreCodec, encode_packet  # noqa: E402
from drivers.irboard.canframe import pack_sample  # noqa: E402
from drivers.irboard.codec import IrCanCodec, IrSerialCodec  # noqa: E402
from drivers.irboard.serialframe import RawSample, encode_sample  # noqa: E402
from drivers.nmea.codec import NmeaCodec  # noqa: E402
from drivers.nmea.writer import epoch_sentences  # noqa: E402
from msgs import GpsFix  # noqa: E402

SIP = frame(0x33, encode_sip({"XPOS": 100, "YPOS": 200, "THPOS": 5, "L_VEL": 100, "R_VEL": 120,
                              "BATTERY": 128, "FLAGS": 1, "BATTERYX10": 128, "ROTVEL": 10,
                              "FAULTFLAGS": 0}))  # fmt: skip
SIP_STREAM = SIP * 1000


def sip_decode() -> int:
    codec = ArcosCodec()
    codec.feed(SIP_STREAM, 0)
    return 1000


def command_encode() -> int:
    for i in range(1000):
        encode_command(Cmd.VEL, i - 500)
    return 1000


SAMPLES = [RawSample(1, i & 0xFFFF, 10, tuple((i * 7 + k * 97) % 1024 for k in range(6)))
           for i in range(1000)]  # fmt: skip
IR_STREAM = b"".join(encode_sample(x) for x in SAMPLES)
IR_FRAMES = [pack_sample(x) for x in SAMPLES]
GYRO_STREAM = b"".join(encode_packet(0.01 * (i % 50), 0.001 * i) for i in range(1000))


def _nmea_sentences(epochs: int = 200) -> bytes:
    out = []
    for i in range(epochs):
        fix = GpsFix(0, lat_deg=37.5665 + 1e-6 * i, lon_deg=126.978 - 1e-6 * i, alt_msl_m=38.5,
                     geoid_sep_m=18.2, mode=3, quality=1, satellites=9, hdop=0.9, pdop=1.6,
                     vdop=1.3, speed_mps=1.2, course_deg=87.0, std_lat_m=1.1, std_lon_m=1.0,
                     std_alt_m=2.0)  # fmt: skip
        when = dt.datetime(2026, 11, 23, 9, 0, i % 60, tzinfo=dt.UTC)
        out.append(epoch_sentences(fix, when + dt.timedelta(minutes=i // 60)))
    return b"".join(out)


NMEA_STREAM = _nmea_sentences()
NMEA_LINES = [line.decode("ascii") for line in NMEA_STREAM.splitlines() if line]


def ir_serial_decode() -> int:
    IrSerialCodec().feed(IR_STREAM, 0)
    return len(SAMPLES)


def ir_can_decode() -> int:
    codec = IrCanCodec()
    for arb, data in IR_FRAMES:
        codec.feed_frame(arb, data, 0)
    return len(IR_FRAMES)


def gyro_decode() -> int:
    CruzCoreCodec().feed(GYRO_STREAM, 0)
    return 1000


def nmea_decode() -> int:
    NmeaCodec().feed(NMEA_STREAM, 0)
    return len(NMEA_LINES)


def pynmea2_parse() -> int:
    import pynmea2

    for line in NMEA_LINES:
        pynmea2.parse(line, check=True)
    return len(NMEA_LINES)


BENCHES: dict[str, Callable[[], int]] = {
    "arcos_sip_decode_per_s": sip_decode,
    "arcos_command_encode_per_s": command_encode,
    "ir_serial_frame_decode_per_s": ir_serial_decode,
    "ir_can_frame_decode_per_s": ir_can_decode,
    "gyro_packet_decode_per_s": gyro_decode,
    "nmea_sentence_decode_per_s": nmea_decode,
    "pynmea2_sentence_parse_per_s": pynmea2_parse,
}


def rate(fn: Callable[[], int], seconds: float = 1.0) -> float:
    n = 0
    t0 = time.perf_counter()
    while (dt := time.perf_counter() - t0) < seconds:
        n += fn()
    return n / dt


def check() -> None:
    """The streams decode completely (a rate of nothing would be meaningless)."""
    assert len(IrSerialCodec().feed(IR_STREAM, 0)) == len(SAMPLES)
    assert len(CruzCoreCodec().feed(GYRO_STREAM, 0)) == 1000
    fixes = NmeaCodec().feed(NMEA_STREAM, 0)
    assert len(fixes) >= 199 and fixes[0].mode == 3, len(fixes)


def main() -> dict[str, float]:
    check()
    results: dict[str, float] = {name: round(rate(fn)) for name, fn in BENCHES.items()}
    results["nmea_vs_pynmea2"] = round(
        results["nmea_sentence_decode_per_s"] / results["pynmea2_sentence_parse_per_s"], 2
    )
    for name, value in results.items():
        print(f"{name:40s} {value:>12,}")
    print(json.dumps(results))
    return results


if __name__ == "__main__":
    main()
