"""Benchmark: what this machine's scheduler adds to a Zenoh put's delivery when the
sender goes on working (the floor under the daemon's pose latency).

The daemon puts the pose, then runs cooperative localization's step in the same
thread. This bench isolates that pattern with nothing else running: a second Python
process (the sender) puts its clock, express, 20 times a second over loopback TCP to a
session of this process, and after each put

- ``idle``: sleeps;
- ``busy_gil_MS``: computes for MS ms holding the GIL (pure Python);
- ``busy_nogil_MS``: computes for MS ms with the GIL released (hashing 64 KiB blocks);
- ``yield_busy_MS``: calls ``os.sched_yield()`` first, then computes holding the GIL.

It prints the delivery time (put to arrival in this process's callback) p50 / p90 /
p99 per case, and, the LAST line, a JSON object with them. On a machine whose scheduler
runs Zenoh's sending thread at once, every case is the idle one; where the busy cases
are longer by about the work's length, a sender's work after a put delays the put.

    python bench/transport_floor.py [--puts 200] [--work-ms 0.5 2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hilnav.bus import free_tcp_port

SENDER = """
import hashlib, json, os, sys, time, zenoh
endpoint, kind, work_s, puts = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
conf = zenoh.Config()
conf.insert_json5("mode", '"peer"')
conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
conf.insert_json5("listen/endpoints", "[]")
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
pub = session.declare_publisher("hilnav-bench/floor", express=True)
time.sleep(1.0)  # the route to the subscriber is declared
block = b"x" * 65536
for _ in range(puts):
    pub.put(str(time.time_ns()).encode() + b" " * 300)  # about a pose's size
    if kind == "yield":
        os.sched_yield()
    end = time.perf_counter() + work_s
    if kind == "nogil":
        while time.perf_counter() < end:
            hashlib.sha256(block).digest()
    else:
        while time.perf_counter() < end:
            pass
    time.sleep(0.05)
session.close()
"""


def run_case(session, port: int, kind: str, work_ms: float, puts: int) -> list[float]:
    """Delivery times (ms) of one sender's puts; the first 5 left out (warm-up)."""
    got: list[float] = []

    def on(sample) -> None:
        now = time.time_ns()
        got.append((now - int(bytes(sample.payload).split()[0])) * 1e-6)

    sub = session.declare_subscriber("hilnav-bench/floor", on)
    try:
        subprocess.run(
            [sys.executable, "-c", SENDER, f"tcp/127.0.0.1:{port}", kind, str(work_ms / 1e3),
             str(puts)],
            check=True, timeout=60 + puts,
        )  # fmt: skip
        time.sleep(0.2)
    finally:
        sub.undeclare()
    return got[5:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--puts", type=int, default=200, help="puts per case")
    ap.add_argument("--work-ms", type=float, nargs="+", default=[0.5, 2.0],
                    help="the sender's work after each put, ms")  # fmt: skip
    args = ap.parse_args(argv)
    import zenoh

    port = free_tcp_port()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    cases = [("idle", "idle", 0.0)]
    for ms in args.work_ms:
        cases += [(f"busy_gil_{ms:g}", "gil", ms), (f"busy_nogil_{ms:g}", "nogil", ms),
                  (f"yield_busy_{ms:g}", "yield", ms)]  # fmt: skip
    result: dict[str, object] = {"bench": "transport_floor", "puts": args.puts}
    print(f"{'case':<18} {'n':>4} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8}")
    try:
        for name, kind, ms in cases:
            v = run_case(session, port, kind, ms, args.puts)
            q = [round(float(np.percentile(v, p)), 3) if v else None for p in (50, 90, 99)]
            print(
                f"{name:<18} {len(v):>4} "
                + " ".join(f"{x if x is not None else '-':>8}" for x in q)
            )
            result[f"{name}_ms_p50"], result[f"{name}_ms_p90"], result[f"{name}_ms_p99"] = q
            result[f"{name}_n"] = len(v)
    finally:
        session.close()
    result["load_average_1min"] = round(os.getloadavg()[0], 2)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
