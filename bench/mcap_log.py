"""MCAP log throughput: writer messages/s and bytes/message, reader and recover rates.

A daemon-like message mix per 10 ms tick (gyro 100 Hz; odometry, heading, pose 10 Hz; IR
20 Hz; raw bytes of two devices; GPS 1 Hz; CP box 2 Hz), written with the Foxglove views
(the default) and without. Rates are per second of the process's CPU time, the best of
``--rounds`` (5) rounds, so that other work on the machine counts less. Prints JSON on its
last line.

    python bench/mcap_log.py [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hilnav.log.reader import ReadStats, read_messages
from hilnav.log.recover import recover
from hilnav.log.writer import LogWriter
from msgs import (
    GpsFix,
    GyroSample,
    HeadingEstimate,
    Interval,
    IrScan,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RawBytes,
    RobotOdometry,
)

T0 = 1_700_000_000_000_000_000
TICKS = 3000  # 30 s of robot time


def messages(tick: int) -> list[tuple[str, object]]:
    t = T0 + tick * 10_000_000
    x = 0.003 * tick
    out: list[tuple[str, object]] = [
        ("/r1/gyro", GyroSample(t, 0.01, 0.001 * tick, 0.001 * tick)),
        ("/r1/raw/gyro", RawBytes(t, "gyro", b"\xff\xff\x10\x00\x20\x00\x2f\x00")),
    ]
    if tick % 5 == 0:
        ranges = tuple(1.0 + 0.01 * k for k in range(6))
        out.append(("/r1/ir", IrScan(t, 1, tick // 5, ranges, ("ok",) * 6, (1.2,) * 6)))
    if tick % 10 == 0:
        p = Pose2D(x, 0.1, 0.05)
        out += [
            ("/r1/odometry", RobotOdometry(t, p, 0.3, 0.3, 0.3, 0.0, 12.6, True, True,
                                           raw={"XPOS": tick, "YPOS": 3, "THPOS": 9})),
            ("/r1/raw/arcos", RawBytes(t, "arcos", bytes(range(40)))),
            ("/r1/heading", HeadingEstimate(t, 0.05, 1e-4, p)),
            ("/r1/pose", PoseEstimate(t, p, (0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001))),
        ]  # fmt: skip
    if tick % 50 == 0:
        box = PoseBox(t, "r1", Interval(x - 0.3, x + 0.3), Interval(-0.2, 0.4), Interval(0, 0.1))
        out.append(("/r1/pose_box", box))
    if tick % 100 == 0:
        out.append(("/r1/gps", GpsFix(t, lat_deg=37.56, lon_deg=126.97, hdop=0.9, mode=3)))
    return out


def best_cpu_s(fn: Callable[[], object], rounds: int) -> tuple[float, object]:
    """The least CPU time of ``rounds`` calls of ``fn``, and its last result."""
    best, out = float("inf"), None
    for _ in range(rounds):
        start = time.process_time()
        out = fn()
        best = min(best, time.process_time() - start)
    return best, out


def bench_write(
    path: Path, views: bool, compression: str = "zstd", rounds: int = 5
) -> dict[str, float]:
    items = [(topic, msg, T0 + i * 10_000_000) for i in range(TICKS) for topic, msg in messages(i)]

    def write() -> int:
        with LogWriter(path, compression=compression, foxglove_views=views) as w:
            for topic, msg, t in items:
                w.write(topic, msg, t)
            return w.messages_written

    dt, written = best_cpu_s(write, rounds)
    size = path.stat().st_size
    return {
        "calls": len(items),
        "records": written,
        "calls_per_s": len(items) / dt,
        "records_per_s": written / dt,
        "bytes_per_record": size / written,
        "file_bytes": size,
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5, help="rounds per figure; the best counts")
    rounds = ap.parse_args(argv).rounds
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        res: dict[str, object] = {}
        res["write_zstd_views"] = bench_write(tmp / "a.mcap", True, rounds=rounds)
        res["write_zstd_native_only"] = bench_write(tmp / "b.mcap", False, rounds=rounds)
        res["write_lz4_views"] = bench_write(tmp / "c.mcap", True, "lz4", rounds=rounds)

        def read() -> tuple[int, ReadStats]:
            st = ReadStats()
            return sum(1 for _ in read_messages(tmp / "a.mcap", stats=st)), st

        dt, (n, st) = best_cpu_s(read, rounds)  # type: ignore[misc]
        res["read_decode"] = {
            "messages": n,
            "records": st.messages,
            "records_per_s": st.messages / dt,
        }
        data = (tmp / "a.mcap").read_bytes()
        (tmp / "cut.mcap").write_bytes(data[: len(data) * 2 // 3])
        dt, rep = best_cpu_s(lambda: recover(tmp / "cut.mcap", tmp / "rec.mcap"), rounds)
        res["recover"] = {"messages": rep.messages, "messages_per_s": rep.messages / dt}
        for name, r in res.items():
            print(
                f"{name:24s} "
                + ", ".join(
                    f"{k}={v:.1f}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()
                )
            )  # type: ignore[union-attr]
        headline = res["write_zstd_views"]
        print(json.dumps({
            "writer_messages_per_s": round(headline["calls_per_s"]),  # type: ignore[index]
            "writer_records_per_s": round(headline["records_per_s"]),  # type: ignore[index]
            "bytes_per_record": round(headline["bytes_per_record"], 1),  # type: ignore[index]
            "native_only_messages_per_s": round(res["write_zstd_native_only"]["calls_per_s"]),  # type: ignore[index]
            "native_only_bytes_per_record": round(res["write_zstd_native_only"]["bytes_per_record"], 1),  # type: ignore[index]
            "lz4_messages_per_s": round(res["write_lz4_views"]["calls_per_s"]),  # type: ignore[index]
            "lz4_bytes_per_record": round(res["write_lz4_views"]["bytes_per_record"], 1),  # type: ignore[index]
            "read_records_per_s": round(res["read_decode"]["records_per_s"]),  # type: ignore[index]
            "recover_messages_per_s": round(res["recover"]["messages_per_s"]),  # type: ignore[index]
            "load_average_1min": round(os.getloadavg()[0], 2),
        }))  # fmt: skip


if __name__ == "__main__":
    main()
