"""Mutation fuzzing of every codec: crashes, phantom frames, intact frames lost. JSON last.

``python3 bench/fuzz.py [--streams N] [--seed S] [--jobs J]`` feeds N mutated streams to
each codec (ARCOS, IR board on serial and on CAN, CruzCore gyro, NMEA). The clean streams
are fixed and made with the project's encoders; stream i of a codec is mutated by
``random.Random(f"{S}:{codec}:{i}")`` with the kinds of tests/codec_fuzz.py (byte flips,
inserts, deletes, truncations, garbage splices, maxed length fields, checksum-valid field
mutations, duplicates, drops) and fed in random chunks, so a run is reproducible and any
stream can be replayed alone. Per codec the table gives streams, crashes, phantom frames,
intact frames lost after the damage (and before it, which should never happen), intact
frames decoded late (by a later feed than the one completing them), damaged frames that
passed the protocol's checks (accepted), intact frames swallowed by such a frame
overlapping them (neither is a fault: the protocol cannot tell them from real ones) and
the CPU seconds. ``--jobs`` splits the streams over processes. The last line is one JSON
object of those figures.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.codec_fuzz import Tally, fuzz_one
from tests.codec_streams import STREAMS

COLUMNS = ("streams", "crashes", "phantoms", "lost_after_damage", "lost_before_damage", "late",
           "accepted_damaged", "swallowed", "seconds")  # fmt: skip
HEADS = ("streams", "crashes", "phantoms", "lost after", "lost before", "late", "accepted",
         "swallowed", "cpu s")  # fmt: skip


def fuzz_range(name: str, seed: int, start: int, stop: int) -> Tally:
    """Streams ``start`` .. ``stop`` - 1 of one codec."""
    adapter = STREAMS[name]()
    total = Tally()
    t0 = time.process_time()
    for i in range(start, stop):
        total.add(fuzz_one(adapter, random.Random(f"{seed}:{name}:{i}")))
    total.seconds = time.process_time() - t0
    return total


def run(streams: int, seed: int, jobs: int) -> dict[str, Tally]:
    parts = jobs * 4 if jobs > 1 else 1
    bounds = [streams * k // parts for k in range(parts + 1)]
    work = [(name, seed, bounds[k], bounds[k + 1]) for name in STREAMS for k in range(parts)]
    work = [w for w in work if w[3] > w[2]]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = [pool.submit(fuzz_range, *w) for w in work]
            tallies = [r.result() for r in results]
    else:
        tallies = [fuzz_range(*w) for w in work]
    out = {name: Tally() for name in STREAMS}
    for w, tally in zip(work, tallies, strict=True):
        out[w[0]].add(tally)
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--streams", type=int, default=25000, help="streams per codec (25000)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the mutations (1)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (1)")
    args = ap.parse_args(argv)
    wall = time.monotonic()
    tallies = run(args.streams, args.seed, args.jobs)
    wall = time.monotonic() - wall
    print(f"{'codec':10s}" + "".join(f"{h:>12s}" for h in HEADS))
    for name, t in tallies.items():
        t.seconds = round(t.seconds, 1)
        print(f"{name:10s}" + "".join(f"{getattr(t, c):>12}" for c in COLUMNS))
    crashes = [t.first_crash for t in tallies.values() if t.first_crash]
    for c in crashes:
        print("first crash:", c)
    result = {
        "streams_per_codec": args.streams,
        "seed": args.seed,
        "jobs": args.jobs,
        "wall_s": round(wall, 1),
        "codecs": {n: {c: getattr(t, c) for c in COLUMNS} for n, t in tallies.items()},
        "total": {c: sum(getattr(t, c) for t in tallies.values()) for c in COLUMNS},
        "first_crashes": crashes,
    }
    result["total"]["seconds"] = round(result["total"]["seconds"], 1)
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
