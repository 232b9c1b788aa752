"""The daemon bench's floors (``bench/daemon.py``): the wake floor's process is woken as
often as asked and says what its waits cost; the context-switch count reads every thread."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_daemon", ROOT / "bench" / "daemon.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_daemon"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_the_wake_floor_is_a_finite_share_of_a_core() -> None:
    bench = _bench()
    floor = bench.WakeFloor(1.0, hz=40.0)
    time.sleep(1.2)
    percent = floor.close()
    assert math.isfinite(percent)
    assert 0.0 < percent < 100.0  # woken 40 times, each wait and read costs something


def test_a_wake_floor_whose_process_failed_says_nan(capsys) -> None:
    bench = _bench()
    floor = bench.WakeFloor(0.5, hz=10.0)
    floor.proc.kill()
    assert math.isnan(floor.close())
    assert "wake floor" in capsys.readouterr().err


def test_voluntary_switches_count_every_thread() -> None:
    bench = _bench()
    before = bench.voluntary_switches(os.getpid())
    slept, counted = threading.Event(), threading.Event()

    def waits() -> None:
        for _ in range(20):
            time.sleep(0.001)  # each sleep ends a wait: one voluntary switch
        slept.set()
        counted.wait(10)  # alive (its /proc entry kept) until counted

    t = threading.Thread(target=waits)
    t.start()
    assert slept.wait(10)
    after = bench.voluntary_switches(os.getpid())
    counted.set()
    t.join()
    assert after - before >= 20


def test_the_transport_floor_bench_measures_every_case(capsys) -> None:
    """``bench/transport_floor.py`` on a few puts: each case's deliveries arrive and are
    timed (the warm-up's five left out), the last line is its JSON."""
    spec = importlib.util.spec_from_file_location(
        "bench_transport_floor", ROOT / "bench" / "transport_floor.py"
    )
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--puts", "10", "--work-ms", "0.5"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["bench"] == "transport_floor"
    for case in ("idle", "busy_gil_0.5", "busy_nogil_0.5", "yield_busy_0.5"):
        assert 4 <= result[f"{case}_n"] <= 5  # (a put lost on loopback: rare, allowed)
        p50, p99 = result[f"{case}_ms_p50"], result[f"{case}_ms_p99"]
        assert 0.0 < p50 <= p99 < 1000.0


def test_the_daemons_threads_are_named_for_the_os_and_their_cpu_told_apart() -> None:
    """hilnav.osthread.NamedThread gives its name to its OS thread, which is how the
    bench tells the device loop's CPU from the mapping's (``cpu_percent_threads``)."""
    from hilnav.osthread import NamedThread

    bench = _bench()
    stop = threading.Event()

    def spin() -> None:
        end = time.process_time() + 0.3
        while time.process_time() < end and not stop.is_set():
            sum(range(1000))
        stop.wait(5.0)

    before = bench.thread_cpu(os.getpid())
    t = NamedThread(target=spin, name="mapping", daemon=True)
    t.start()
    try:
        time.sleep(0.1)
        comm = Path(f"/proc/{os.getpid()}/task/{t.native_id}/comm").read_text().strip()
        assert comm == "mapping"
        deadline = time.monotonic() + 5.0
        while bench.thread_cpu(os.getpid())["mapping"] - before["mapping"] < 0.2:
            assert time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        stop.set()
        t.join(5.0)
    assert set(before) == {"services", "mapping", "watchdog", "mcap-flush", "zenoh", "other"}


def test_the_table_puts_a_baselines_figures_beside_this_checkouts(capsys) -> None:
    """``--baseline``: the old checkout's figures (an old bench has no per-thread split)
    in a column beside this run's; a baseline that failed is said, not tabled."""
    bench = _bench()
    run = {
        "cpu_percent_daemon": 5.8,
        "cpu_percent_threads": {"services": 2.4, "mapping": 2.5},
        "daemon_wakeups_per_s": 170.0,
        "wake_floor_percent": 0.4,
        "cpu_percent_fakes": 4.8,
        "peak_rss_mb_daemon": 99.0,
        "pose_latency_ms_p50": 1.1,
        "pose_latency_ms_p99": 3.3,
        "transport_ms_p50": 0.3,
        "transport_ms_p99": 2.5,
        "mcap_messages_per_s": 283.0,
        "dropped": 0,
        "load_average_1min": 0.9,
    }
    old = {**run, "cpu_percent_daemon": 7.1, "daemon_wakeups_per_s": 319.0}
    del old["cpu_percent_threads"]
    bench.print_table({**run, "baseline": old})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[-3:] == ["baseline", "this", "checkout"]
    cpu = next(x for x in lines if x.startswith("daemon CPU"))
    assert cpu.split()[-2:] == ["7.1", "5.8"]
    mapping = next(x for x in lines if "thread mapping" in x)
    assert mapping.split()[-2:] == ["-", "2.5"]
    bench.print_table({**run, "baseline": {"error": "baseline bench/daemon.py failed (1)"}})
    out = capsys.readouterr()
    assert "failed" in out.err and out.out.splitlines()[0].split() == ["figure", "value"]
