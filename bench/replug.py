"""Unplug and replug: how long after a port comes back do its messages flow again?

Each device's emulated twin runs on a pty behind a stable link; its driver reads in a
thread as the daemon's would. A cycle pulls the "cable" (the pty is closed and the link
removed, as when a USB adapter goes), waits a random 0.2-2 s outage, plugs it back (a
new pty under the same path) and measures the time from the port's return to the first
message the driver decodes after it (and to its first bytes: a 1 Hz GPS delivers its
next fix up to a second after its bytes flow again). Prints a table and, on its last line, one JSON object
(per device: cycles, median/p95/max seconds, cycles over 1 s). Real ptys, real drivers;
the outage lengths are seeded.

    python bench/replug.py [--cycles 100] [--devices arcos,gyro,ir,gps] [--seed 1]
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hilnav.config import parse_config
from hilnav.devices import DEVICES, FakeKnobs
from hilnav.fakeset import build_fakes


class Reader:
    """The driver's read loop in a thread; remembers when the last message arrived."""

    def __init__(self, make: Any) -> None:
        self.driver = make(self._raw)
        self.last = 0.0
        self.last_raw = 0.0
        self.count = 0
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    def _raw(self, data: bytes, stamp_ns: int) -> None:
        self.last_raw = time.monotonic()

    def start(self) -> None:
        try:
            self.driver.open()
        except Exception:
            pass
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            if self.driver.read(0.05):
                self.last = time.monotonic()
                self.count += 1

    def stop(self) -> None:
        self._stop.set()
        self._t.join(2.0)
        self.driver.close()


def _wait(cond: Any, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return False


def run_device(
    name: str, cycles: int, rng: random.Random, tmp: Path
) -> tuple[list[float], list[float], list[float]]:
    """Replug latencies (s) of one device: to the driver's link open again, to the first
    bytes and to the first message;
    inf for a cycle whose data never came back."""
    data = {"devices": {"ir": {"link": "serial"}}, "simulation": {"seed": rng.randrange(99)}}
    cfg = parse_config(data, "<bench>")
    runner = build_fakes(cfg, FakeKnobs(link_dir=str(tmp / name)), devices=[name])
    runner.start()
    emu = runner.emulators[0]
    port = emu.port
    data["devices"] = {name: {"port": port.path}, "ir": {"link": "serial", "port": port.path}}
    cfg = parse_config(data, "<bench>")
    reader = Reader(lambda hook: DEVICES[name].driver(cfg, hook))
    reader.start()
    out: list[float] = []
    link: list[float] = []
    reopen: list[float] = []
    try:
        for _ in range(cycles):
            if not _wait(lambda: time.monotonic() - reader.last < 0.2, 10.0):
                out.append(float("inf"))
            port.vanish()
            time.sleep(rng.uniform(0.2, 2.0))
            back = time.monotonic()
            port.reappear()
            _wait(lambda: reader.driver.connected, 10.0)
            reopen.append(time.monotonic() - back)
            got = _wait(lambda b=back: reader.last > b, 10.0)
            out.append(reader.last - back if got else float("inf"))
            link.append(reader.last_raw - back if reader.last_raw > back else float("inf"))
    finally:
        reader.stop()
        runner.stop()
    return reopen, link, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=20)
    ap.add_argument("--devices", default="arcos,gyro,ir,gps")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    import tempfile

    rng = random.Random(args.seed)
    result: dict[str, Any] = {"bench": "replug", "cycles": args.cycles}
    print(f"{'device':8s} {'cycles':>6s} {'reopen max s':>12s} {'bytes med s':>11s} {'msg med s':>9s} {'p95 s':>7s} "
          f"{'max s':>7s} {'>1 s':>5s}")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="hilnav-replug-") as tmp:
        for name in args.devices.split(","):
            reopen, link, lat = run_device(name, args.cycles, rng, Path(tmp))
            lat.sort()
            p95 = lat[min(len(lat) - 1, int(0.95 * len(lat)))]
            row = {
                "reopen_median_s": round(statistics.median(reopen), 3),
                "reopen_max_s": round(max(reopen), 3),
                "bytes_median_s": round(statistics.median(link), 3),
                "bytes_max_s": round(max(link), 3),
                "median_s": round(statistics.median(lat), 3),
                "p95_s": round(p95, 3),
                "max_s": round(lat[-1], 3),
                "over_1s": sum(x > 1.0 for x in lat),
            }
            result[name] = row
            print(f"{name:8s} {len(lat):6d} {row['reopen_max_s']:12.3f} {row['bytes_median_s']:11.3f} {row['median_s']:9.3f} "
                  f"{row['p95_s']:7.3f} "
                  f"{row['max_s']:7.3f} {row['over_1s']:5d}")  # fmt: skip
    result["over_1s_total"] = sum(v["over_1s"] for v in result.values() if isinstance(v, dict))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
