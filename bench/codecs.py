"""Codec throughput: decode and encode rates per second. Prints JSON on its last line.

Each entry of BENCHES is a name -> (function, units per call). Sensor codecs add theirs.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable

from drivers.arcos import ArcosCodec, Cmd, encode_command, frame
from drivers.arcos.packets import encode_sip

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


BENCHES: dict[str, Callable[[], int]] = {
    "arcos_sip_decode_per_s": sip_decode,
    "arcos_command_encode_per_s": command_encode,
}


def rate(fn: Callable[[], int], seconds: float = 1.0) -> float:
    n = 0
    t0 = time.perf_counter()
    while (dt := time.perf_counter() - t0) < seconds:
        n += fn()
    return n / dt


def main() -> dict[str, float]:
    results = {name: round(rate(fn)) for name, fn in BENCHES.items()}
    for name, value in results.items():
        print(f"{name:40s} {value:>12,}")
    print(json.dumps(results))
    return results


if __name__ == "__main__":
    main()
