"""Codec throughput: decode and encode rates per second, and their multiple of the line
rate. Prints a table, then JSON on its last line.

Each entry of BENCHES is a name -> (function returning the units it processed, the units
per second the device's line carries at most). ARCOS SIPs and commands at 9600 baud; IR
board frames on a 115200 baud serial line and CAN frames against a full 500 kbit/s bus
(47 bits of frame overhead plus 8 per data byte, bit stuffing left out, so the bus rate is
if anything too high), both with conversion to ranges; CruzCore gyro packets at 115200
baud; NMEA sentences at 9600 baud (framing, checksum, gpsd's rules, epoch combining, and
reading a fix's time, position, altitude, mode, satellites, HDOP, speed and track) and,
on the same sentences, pynmea2 parsing them and reading the same typed fields as the
baseline (``nmea_vs_pynmea2`` = our rate over pynmea2's; pynmea2 neither frames a byte
stream nor combines epochs). The same pair runs on a second stream, a moving receiver's
(``nmea_vs_pynmea2_moving``), where the altitude, speed, course, GST sigmas and now and
then the DOPs and satellites change every epoch, so fewer fields repeat. A third pair runs
on real receivers' sentences (``nmea_vs_pynmea2_real``): every gpsd regression log in
``shared/data/gpsd`` (``HILNAV_SHARED`` points at another shared folder), their sentences
concatenated in one stream; a sentence pynmea2 cannot parse, or whose fields it cannot
read, is counted (``nmea_real_skipped``) and left out of both streams. A serial line
carries 10 bits per byte (8N1).

``--baseline OLD_CHECKOUT`` measures that checkout's codecs with this script (in a
subprocess importing that checkout's packages) between our rounds and prints its rates
beside ours (bench/baseline.py).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

# The code under test: this checkout's, or (HILNAV_BENCH_CODE, set by --baseline) another's.
if __package__ in (None, "") or "HILNAV_BENCH_CODE" in os.environ:
    sys.path.insert(
        0, os.environ.get("HILNAV_BENCH_CODE", str(Path(__file__).resolve().parents[1]))
    )
from drivers.arcos import ArcosCodec, Cmd, encode_command, frame
from drivers.arcos.packets import encode_sip
from drivers.cruzcore import CruzCoreCodec, encode_packet
from drivers.irboard.canframe import pack_sample
from drivers.irboard.codec import IrCanCodec, IrSerialCodec
from drivers.irboard.serialframe import RawSample, encode_sample
from drivers.nmea.codec import NmeaCodec

try:
    from drivers.nmea import clear_caches
except ImportError:  # (older code, whose tables stay filled from call to call)

    def clear_caches() -> None:
        pass


from drivers.nmea.writer import epoch_sentences
from msgs import GpsFix

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


def _nmea_sentences(epochs: int = 200, moving: bool = False) -> bytes:
    """A receiver's epochs (GGA, GSA, RMC, VTG, GST, ZDA). ``moving``: besides the
    position, the altitude, speed, course, GST sigmas and, now and then, the DOPs and the
    satellites change from epoch to epoch (fewer repeated fields to read once)."""
    out = []
    for i in range(epochs):
        fix = GpsFix(0, lat_deg=37.5665 + 1e-6 * i, lon_deg=126.978 - 1e-6 * i, alt_msl_m=38.5,
                     geoid_sep_m=18.2, mode=3, quality=1, satellites=9, hdop=0.9, pdop=1.6,
                     vdop=1.3, speed_mps=1.2, course_deg=87.0, std_lat_m=1.1, std_lon_m=1.0,
                     std_alt_m=2.0)  # fmt: skip
        if moving:
            step = (i // 13) % 4 * 0.1
            fix = replace(fix, lat_deg=37.5665 + 1e-5 * i, lon_deg=126.978 - 1e-5 * i,
                          alt_msl_m=38.5 + 0.37 * math.sin(i / 7), satellites=9 + i // 50 % 3,
                          hdop=0.9 + step, pdop=1.6 + step, speed_mps=1.2 + 0.5 * math.sin(i / 5),
                          course_deg=(87.0 + 3.3 * i) % 360, std_lat_m=1.1 + 0.01 * (i % 17),
                          std_lon_m=1.0 + 0.01 * (i % 11), std_alt_m=2.0 + 0.01 * (i % 7))  # fmt: skip
        when = dt.datetime(2026, 11, 23, 9, 0, i % 60, tzinfo=dt.UTC)
        out.append(epoch_sentences(fix, when + dt.timedelta(minutes=i // 60)))
    return b"".join(out)


NMEA_STREAM = _nmea_sentences()
NMEA_LINES = [line.decode("ascii") for line in NMEA_STREAM.splitlines() if line]
NMEA_MOVING = _nmea_sentences(moving=True)
NMEA_MOVING_LINES = [line.decode("ascii") for line in NMEA_MOVING.splitlines() if line]


def _real_sentences() -> tuple[bytes, list[str], int]:
    """The sentences of every gpsd log in the shared folder: (the stream, its lines, the
    number left out because pynmea2 fails on them). Comment and blank lines are no
    sentences."""
    shared = Path(os.environ.get("HILNAV_SHARED", Path(__file__).resolve().parents[2] / "shared"))
    lines: list[str] = []
    skipped = 0
    for log in sorted((shared / "data" / "gpsd").glob("*.log")):
        for raw in log.read_bytes().splitlines():
            if not raw.startswith(b"$"):
                continue
            try:
                line = raw.decode("ascii")
                pynmea2_parse([line])
            except Exception:  # (pynmea2's parse errors, and its fields' on odd values)
                skipped += 1
                continue
            lines.append(line)
    return "".join(f"{line}\r\n" for line in lines).encode("ascii"), lines, skipped


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


def nmea_decode(stream: bytes = NMEA_STREAM, lines: list[str] = NMEA_LINES) -> int:
    """Our codec on a stream, from empty tables of read fields (drivers/nmea/memo.py): a
    stream decoded again would otherwise find its fields read already."""
    clear_caches()
    for m in NmeaCodec().feed(stream, 0):
        if isinstance(m, GpsFix):
            _ = (m.time_utc, m.lat_deg, m.lon_deg, m.alt_msl_m, m.mode, m.satellites, m.hdop)
            _ = (m.speed_mps, m.course_deg)
    return len(lines)


def pynmea2_parse(lines: list[str] = NMEA_LINES) -> int:
    """pynmea2 on the same sentences, reading the typed fields a fix needs."""
    import pynmea2

    for line in lines:
        m = pynmea2.parse(line, check=True)
        kind = m.sentence_type
        if kind == "GGA":
            _ = (m.timestamp, m.latitude, m.longitude, m.altitude, m.gps_qual, m.num_sats)
            _ = m.horizontal_dil
        elif kind == "RMC":
            _ = (m.datetime, m.latitude, m.longitude, m.spd_over_grnd, m.true_course)
        elif kind == "GSA":
            _ = (m.mode_fix_type, m.pdop, m.hdop, m.vdop)
        elif kind == "VTG":
            _ = (m.true_track, m.spd_over_grnd_kts)
        elif kind == "ZDA":
            _ = m.datetime
        elif kind == "GLL":
            _ = (m.timestamp, m.latitude, m.longitude)
    return len(lines)


NMEA_REAL, NMEA_REAL_LINES, NMEA_REAL_SKIPPED = _real_sentences()


def _serial(bytes_per_unit: float, baud: int) -> float:
    return baud / 10.0 / bytes_per_unit


CAN_FRAME_BITS = 47 + 8 * len(IR_FRAMES[0][1])
CMD_BYTES = len(encode_command(Cmd.VEL, 100))
BENCHES: dict[str, tuple[Callable[[], int], float]] = {
    "arcos_sip_decode": (sip_decode, _serial(len(SIP), 9600)),
    "arcos_command_encode": (command_encode, _serial(CMD_BYTES, 9600)),
    "ir_serial_frame_decode": (ir_serial_decode, _serial(len(IR_STREAM) / len(SAMPLES), 115200)),
    "ir_can_frame_decode": (ir_can_decode, 500_000 / CAN_FRAME_BITS),
    "gyro_packet_decode": (gyro_decode, _serial(len(GYRO_STREAM) / 1000, 115200)),
    "nmea_sentence_decode": (nmea_decode, _serial(len(NMEA_STREAM) / len(NMEA_LINES), 9600)),
    "pynmea2_sentence_parse": (pynmea2_parse, _serial(len(NMEA_STREAM) / len(NMEA_LINES), 9600)),
    "nmea_moving_decode": (
        lambda: nmea_decode(NMEA_MOVING, NMEA_MOVING_LINES),
        _serial(len(NMEA_MOVING) / len(NMEA_MOVING_LINES), 9600),
    ),
    "pynmea2_moving_parse": (
        lambda: pynmea2_parse(NMEA_MOVING_LINES),
        _serial(len(NMEA_MOVING) / len(NMEA_MOVING_LINES), 9600),
    ),
}
if NMEA_REAL_LINES:  # (without the shared folder's logs, no row)
    BENCHES["nmea_real_decode"] = (
        lambda: nmea_decode(NMEA_REAL, NMEA_REAL_LINES),
        _serial(len(NMEA_REAL) / len(NMEA_REAL_LINES), 9600),
    )
    BENCHES["pynmea2_real_parse"] = (
        lambda: pynmea2_parse(NMEA_REAL_LINES),
        _serial(len(NMEA_REAL) / len(NMEA_REAL_LINES), 9600),
    )


def rate(fn: Callable[[], int], seconds: float = 0.2) -> float:
    """Units per second of this process's CPU time (other processes' load on a shared
    machine slows the wall clock, not this): of the fastest of the calls made in
    ``seconds`` (a call is 1000-1200 units; the fastest is the one other work disturbed
    least, through the caches and the shared core)."""
    best = float("inf")
    t_end = time.process_time() + seconds
    while True:
        t0 = time.process_time()
        n = fn()
        t1 = time.process_time()
        best = min(best, (t1 - t0) / n)
        if t1 >= t_end:
            return 1.0 / best


def best_rates(rounds: int = 5) -> dict[str, float]:
    """Each bench's best rate over ``rounds`` rounds that run every bench in turn, so a
    burst of load on the machine hits all of them alike (NMEA and pynmea2 side by side)."""
    best = dict.fromkeys(BENCHES, 0.0)
    for _ in range(rounds):
        for name, (fn, _line) in BENCHES.items():
            best[name] = max(best[name], rate(fn))
    return best


def check() -> None:
    """The streams decode completely (a rate of nothing would be meaningless)."""
    assert len(IrSerialCodec().feed(IR_STREAM, 0)) == len(SAMPLES)
    assert len(CruzCoreCodec().feed(GYRO_STREAM, 0)) == 1000
    for stream in (NMEA_STREAM, NMEA_MOVING):
        fixes = [m for m in NmeaCodec().feed(stream, 0) if isinstance(m, GpsFix)]
        assert len(fixes) >= 199 and fixes[0].mode == 3, len(fixes)
    if NMEA_REAL_LINES:
        codec = NmeaCodec()
        fixes = [m for m in codec.feed(NMEA_REAL, 0) if isinstance(m, GpsFix)]
        assert codec.stats.frames_ok == len(NMEA_REAL_LINES) and fixes, codec.stats


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=5, help="rounds of every codec (best kept)")
    ap.add_argument(
        "--baseline",
        type=Path,
        help="another hilnav checkout (the old code): its codecs are measured by this script "
        "between our rounds, both figures printed side by side (bench/baseline.py)",
    )
    ap.add_argument("--repeat", type=int, default=3, help="alternations with --baseline")
    args = ap.parse_args(argv)
    check()
    if args.baseline:
        from bench.baseline import merge_best, run_baseline
    names = [f"{n}_per_s" for n in BENCHES]
    ours: dict[str, float] = {}
    theirs: dict[str, float] = {}
    for _ in range(args.repeat if args.baseline else 1):
        rates = {f"{k}_per_s": v for k, v in best_rates(args.rounds).items()}
        ours = {k: max(ours.get(k, 0.0), v) for k, v in rates.items()}
        if args.baseline:
            merge_best(
                theirs, run_baseline(args.baseline, __file__, f"--rounds={args.rounds}"), names
            )
    results: dict = {}
    print(f"{'codec':26s} {'units/s':>12s} {'line rate/s':>12s} {'x line rate':>12s}", end="")
    print(f" {'before/s':>12s} {'before x line':>13s}" if theirs else "")
    for name, (_fn, line_rate) in BENCHES.items():
        r = ours[f"{name}_per_s"]
        results[f"{name}_per_s"] = round(r)
        results[f"{name}_x_line_rate"] = round(r / line_rate, 1)
        print(f"{name:26s} {r:>12,.0f} {line_rate:>12,.1f} {r / line_rate:>12,.1f}", end="")
        old = theirs.get(f"{name}_per_s")
        print(f" {old:>12,.0f} {old / line_rate:>13,.1f}" if old else "")
    if theirs:
        results["baseline"] = {k: round(v) for k, v in theirs.items()}
    if NMEA_REAL_LINES:
        results["nmea_real_sentences"] = len(NMEA_REAL_LINES)
        results["nmea_real_skipped"] = NMEA_REAL_SKIPPED
    for ratio, ours_name, pynmea2_name in RATIOS:
        if f"{ours_name}_per_s" not in results:
            continue
        results[ratio] = round(results[f"{ours_name}_per_s"] / results[f"{pynmea2_name}_per_s"], 2)
        line = f"{ratio:26s} {results[ratio]:>12}"
        if f"{ours_name}_per_s" in theirs:
            before = theirs[f"{ours_name}_per_s"] / theirs[f"{pynmea2_name}_per_s"]
            results["baseline"][ratio] = round(before, 2)
            line += f" {'':>12s} {'':>12s} {before:>12.2f}"
        print(line)
    print(json.dumps(results))
    return results


# ratio -> (our NMEA bench, pynmea2's on the same sentences)
RATIOS = (
    ("nmea_vs_pynmea2", "nmea_sentence_decode", "pynmea2_sentence_parse"),
    ("nmea_vs_pynmea2_moving", "nmea_moving_decode", "pynmea2_moving_parse"),
    ("nmea_vs_pynmea2_real", "nmea_real_decode", "pynmea2_real_parse"),
)


if __name__ == "__main__":
    main()
