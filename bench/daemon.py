"""Benchmark: the robot daemon on the emulated devices at their nominal rates.

Starts ``hilnav run`` on the embedded defaults (simulated Pioneer: SIPs at 10 Hz, IR board
at 20 Hz on CAN through the emulated slcan adapter, gyro at 100 Hz, GPS at 1 Hz; every
service on: heading filter, pose EKF, CP localization, IR mapping with sample-based data
association), drives the demo's office tour over cmd_vel from a second Zenoh session for
``--seconds`` (default 60), then stops the daemon with SIGTERM and reads its MCAP log.

Prints a table, then, the LAST line, a JSON object:
- ``cpu_percent_daemon``: CPU time of the daemon process over the run, in percent of one
  core (``cpu_percent_fakes``: the emulated devices' process, for reference), and
  ``cpu_percent_threads``, the same by thread: the device loop (``services``), the IR
  mapping (``mapping``), the motion watchdog, the log's flush timer, Zenoh's runtime
  (``zenoh``) and the rest (``other``: Python's main thread, zenoh-python's callbacks);
- ``peak_rss_mb_daemon``: the daemon's peak resident memory (VmHWM), MiB;
- ``pose_latency_ms_p50`` / ``_p99``: from the time the Pioneer's bytes were read (the
  odometry stamp, which the pose inherits) to the pose arriving in the second session;
  split, from the log's receive times, into ``pose_hold_ms_*`` (the odometry received to
  the input that released its pose received: the fusion filters take an odometry message
  at once when the gyro has caught up with it, else wait for the gyro sample that covers
  it, fusion.arrival rule 2) and ``pose_after_release_ms_*`` (that input received to the
  pose arriving: the daemon's own work and Zenoh);
- ``transport_ms_p50`` / ``_p99``: the floor under the pose latency on this machine,
  measured at the same time: a second Python process with nothing else to do puts its
  clock 20 times a second to a third Zenoh session of this process over loopback TCP
  (what the pose's last hop is, without the daemon's work);
- ``wake_floor_percent``: the floor under the daemon's CPU on this machine, measured at
  the same time: a second Python process with nothing else to do, woken ``wake_floor_hz``
  times a second (the devices' nominal reads: gyro 100, IR 20, SIPs 10, GPS 1) by a
  pipe it waits on with epoll, reading a few bytes each time (its loop's thread CPU);
  ``daemon_wakeups_per_s``: the daemon's threads' voluntary context switches per second
  (each a wait that ended: a read, a put handed over, a timer);
- ``mcap_messages_per_s``: messages in the log (all topics, raw bytes and Foxglove views
  included) per second of run; ``dropped``: messages the daemon's queues dropped.

``--without SERVICE`` (repeatable: heading, pose, localization, mapping) switches a service
off, to tell the daemon's own costs from a service's.

    python bench/daemon.py [--seconds 60] [--without mapping --without localization]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.baseline import run_baseline
from hilnav.bus import free_tcp_port
from hilnav.commands.demo import TOUR, Operator

ROOT = Path(__file__).resolve().parents[1]


def cpu_seconds(pid: int) -> float:
    """utime + stime of one process (not its children), from /proc."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def peak_rss_mb(pid: int) -> float:
    """The process's peak resident memory (VmHWM) so far, in MiB."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(p) for p in f.read().split()]
    except OSError:
        return []


def output_dir(out: Path | None) -> tuple[Path, tempfile.TemporaryDirectory | None]:
    """The directory for the config and the log: ``out``, or a temporary one (returned too)."""
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="hilnav-bench-daemon-")
        return Path(tmp.name), tmp
    out.mkdir(parents=True, exist_ok=True)
    return out, None


def start_daemon(
    out: Path, port: int, without: tuple[str, ...] = ()
) -> tuple[subprocess.Popen, Path]:
    """``hilnav run`` on the embedded defaults, Zenoh on ``port``, the services ``without``
    off; returns it and its log."""
    cfg = out / "bench-robot.toml"
    off = "".join(f"[services.{name}]\nenabled = false\n" for name in without)
    cfg.write_text(
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{port}"]\ngossip_scouting = true\n[log]\ndir = "{out}"\n'
        + off
    )
    log = out / "bench.mcap"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    proc = subprocess.Popen(
        [sys.executable, "-m", "hilnav", "run", "--config", str(cfg), "--log", str(log), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    return proc, log


PINGER = """
import json, sys, time, zenoh
conf = zenoh.Config()
conf.insert_json5("mode", '"peer"')
conf.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
conf.insert_json5("listen/endpoints", "[]")
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
pub = session.declare_publisher("hilnav-bench/ping")
end = time.monotonic() + float(sys.argv[2])
while time.monotonic() < end:
    pub.put(str(time.time_ns()).encode())
    time.sleep(0.05)
session.close()
"""


class TransportFloor:
    """The pinger's (PINGER, its own process) clock readings, received in a Zenoh session
    of this process that listens on ``port``: ms from each put to its arrival."""

    def __init__(self, port: int, seconds: float) -> None:
        import zenoh

        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
        conf.insert_json5("scouting/multicast/enabled", "false")
        self.values: list[float] = []
        self._session = zenoh.open(conf)
        self._sub = self._session.declare_subscriber("hilnav-bench/ping", self._on)
        self.proc = subprocess.Popen(
            [sys.executable, "-c", PINGER, f"tcp/127.0.0.1:{port}", str(seconds)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip

    def _on(self, sample) -> None:
        now = time.time_ns()
        self.values.append((now - int(bytes(sample.payload))) * 1e-6)

    def close(self) -> None:
        """Stop the pinger (killed if it does not go) and close the session; a pinger
        that failed says so on stderr (its figures are then null)."""
        try:
            self.proc.terminate()
            try:
                _, err = self.proc.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                _, err = self.proc.communicate(timeout=10)
            if self.proc.returncode not in (0, -signal.SIGTERM) and err.strip():
                print(f"transport pinger: {err.strip()[-500:]}", file=sys.stderr)
        finally:
            self._session.close()


WAKEE = """
import os, select, sys, time
fd, seconds = int(sys.argv[1]), float(sys.argv[2])
ep = select.epoll()
ep.register(fd, select.EPOLLIN)
n, t0, end = 0, time.thread_time(), time.monotonic() + seconds
while time.monotonic() < end:
    for _ in ep.poll(0.5):
        if not os.read(fd, 4096):
            end = 0.0
        n += 1
print(n, time.thread_time() - t0)
"""
WAKE_FLOOR_HZ = 131.0  # the devices' nominal reads: gyro 100, IR 20, SIPs 10, GPS 1


class WakeFloor:
    """A process woken ``hz`` times a second by a pipe this process writes to (a thread,
    on an absolute schedule): its loop's CPU is what waking Python costs here."""

    def __init__(self, seconds: float, hz: float = WAKE_FLOOR_HZ) -> None:
        r, self._w = os.pipe()
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WAKEE, str(r), str(seconds)],
            pass_fds=(r,), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        os.close(r)
        self.seconds, self.hz = seconds, hz
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._write, daemon=True)
        self._thread.start()

    def _write(self) -> None:
        t0 = time.monotonic()
        for i in range(int(self.seconds * self.hz)):
            if self._stop.wait(max(0.0, t0 + i / self.hz - time.monotonic())):
                return
            os.write(self._w, b"0123456789abcdef")

    def close(self) -> float:
        """Stop; the wakee's CPU in percent of one core (NaN if it failed, said on stderr)."""
        self._stop.set()
        self._thread.join()
        os.close(self._w)  # the wakee reads end-of-file and stops
        try:
            out, err = self.proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, err = self.proc.communicate(timeout=10)
        try:
            n, cpu = out.split()
            return 100.0 * float(cpu) / (int(n) / self.hz)
        except ValueError:
            print(f"wake floor: {err.strip()[-500:]}", file=sys.stderr)
            return float("nan")


# the daemon's own threads, named for the OS (hilnav.osthread); Zenoh's are "net-0",
# "rx-1", "tx-0", "acc-0", "app-0" ...; the rest (Python's main thread, zenoh-python's
# callback threads) stay "python3"
OWN_THREADS = ("services", "mapping", "watchdog", "mcap-flush")
ZENOH_PREFIXES = ("net-", "rx-", "tx-", "acc-", "app-", "timer", "zenoh")


def thread_cpu(pid: int) -> dict[str, float]:
    """CPU seconds so far of ``pid``'s threads, summed by kind: each of OWN_THREADS,
    "zenoh" (Zenoh's runtime threads) and "other"."""
    out = dict.fromkeys((*OWN_THREADS, "zenoh", "other"), 0.0)
    tick = os.sysconf("SC_CLK_TCK")
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # a thread that ended
            continue
        kind = name if name in out else "zenoh" if name.startswith(ZENOH_PREFIXES) else "other"
        out[kind] += (int(fields[11]) + int(fields[12])) / tick
    return out


def voluntary_switches(pid: int) -> int:
    """The voluntary context switches of every thread of ``pid`` so far."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            with open(task / "status") as f:
                for line in f:
                    if line.startswith("voluntary_ctxt_switches:"):
                        total += int(line.split()[1])
        except OSError:  # a thread that ended
            continue
    return total


class PoseLatencies:
    """Milliseconds from each received pose's stamp to its arrival (a bus callback)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.values: list[float] = []
        self.arrivals: dict[int, int] = {}  # pose stamp -> arrival, ns

    def on_pose(self, robot, msg) -> None:
        now = time.time_ns()
        with self._lock:
            self.values.append((now - msg.stamp_ns) * 1e-6)
            self.arrivals[msg.stamp_ns] = now

    def clear(self) -> None:
        with self._lock:
            self.values.clear()
            self.arrivals.clear()


def latency_split(log: Path, arrivals: dict[int, int]) -> tuple[list[float], list[float]]:
    """Per received pose, from the log: ms from its odometry's receipt to the receipt of
    the input that released the pose (the pose's log time), and ms from then to arrival."""
    from mcap.reader import make_reader

    odometry: dict[int, int] = {}
    released: dict[int, int] = {}
    with open(log, "rb") as f:
        for _, channel, m in make_reader(f).iter_messages(topics=["/r1/odometry", "/r1/pose"]):
            (odometry if channel.topic == "/r1/odometry" else released)[m.publish_time] = m.log_time
    hold, after = [], []
    for stamp, arrived in arrivals.items():
        if stamp in released and stamp in odometry:
            hold.append((released[stamp] - odometry[stamp]) * 1e-6)
            after.append((arrived - released[stamp]) * 1e-6)
    return hold, after


def percentile(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)), 2) if values else float("nan")


def wait_for_robot(op: Operator, proc: subprocess.Popen, timeout_s: float = 60.0) -> bool:
    """Wait (up to ``timeout_s``) for the robot's pose and liveliness; False if it died."""
    t_wait = time.monotonic() + timeout_s
    while time.monotonic() < t_wait and (op.where() is None or not op.alive):
        if proc.poll() is not None:
            print(proc.stderr.read(), file=sys.stderr)
            return False
        time.sleep(0.1)
    return True


def drive_tour(
    op: Operator, proc: subprocess.Popen, latencies: PoseLatencies, seconds: float
) -> tuple[float, float, float, dict[str, float]]:
    """Drive the tour for ``seconds``: CPU seconds of the daemon and of the fakes, elapsed
    s, and the daemon's CPU by thread (percent of one core, :func:`thread_cpu`'s kinds)."""
    fake_pids = children(proc.pid)
    threads0 = thread_cpu(proc.pid)
    cpu0 = cpu_seconds(proc.pid)
    fcpu0 = sum(cpu_seconds(p) for p in fake_pids)
    latencies.clear()
    t0 = time.monotonic()
    deadline = t0 + seconds
    time.sleep(min(2.0, seconds / 4))  # the gyro's bias is learnt at rest
    while time.monotonic() < deadline:
        op.drive(TOUR, 0.5, deadline)
    cpu1 = cpu_seconds(proc.pid)
    threads1 = thread_cpu(proc.pid)
    fcpu1 = sum(cpu_seconds(p) for p in fake_pids)
    elapsed = time.monotonic() - t0
    threads = {k: round(100.0 * (threads1[k] - threads0[k]) / elapsed, 2) for k in threads1}
    return cpu1 - cpu0, fcpu1 - fcpu0, elapsed, threads


def stop_daemon(op: Operator, proc: subprocess.Popen) -> tuple[str, str]:
    """Stop the robot, close the session, SIGTERM the daemon; its stdout and stderr."""
    op.send(0.0, 0.0)
    op.close()
    proc.send_signal(signal.SIGTERM)
    return proc.communicate(timeout=60)


def dropped_messages(stdout: str) -> int | None:
    """The count on the daemon's ``... N dropped`` line, if it printed one."""
    dropped = None
    for line in stdout.splitlines():
        if "dropped" in line:
            dropped = int(line.split(" dropped")[0].rsplit(" ", 1)[1])
    return dropped


def log_statistics(log: Path) -> tuple[int, float]:
    """Messages in the MCAP log and the seconds between its first and last."""
    from mcap.reader import make_reader

    with open(log, "rb") as f:
        summary = make_reader(f).get_summary()
    stats = summary.statistics if summary is not None else None
    n_msgs = stats.message_count if stats is not None else 0
    span_s = (stats.message_end_time - stats.message_start_time) * 1e-9 if stats else 0.0
    return n_msgs, span_s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the run")
    ap.add_argument("--out", type=Path, default=None, help="keep the log in this directory")
    ap.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="another hilnav checkout: its own bench/daemon.py runs at the same time, with "
        "the same options, and its figures are printed beside these (bench/baseline.py)",
    )
    ap.add_argument(
        "--without",
        action="append",
        default=[],
        choices=("heading", "pose", "localization", "mapping"),
        help="switch this service off (repeatable)",
    )
    args = ap.parse_args(argv)
    before = Baseline(args) if args.baseline is not None else None
    out, tmp = output_dir(args.out)
    port = free_tcp_port()
    proc, log = start_daemon(out, port, tuple(args.without))
    op = Operator("r1", port)
    latencies = PoseLatencies()
    op.bus.subscribe("r1", "pose", latencies.on_pose)
    if not wait_for_robot(op, proc):
        return 1
    floor = TransportFloor(free_tcp_port(), args.seconds + 5.0)
    wake = WakeFloor(args.seconds)
    switches0 = voluntary_switches(proc.pid)
    try:
        cpu, fcpu, elapsed, threads = drive_tour(op, proc, latencies, args.seconds)
        switches = voluntary_switches(proc.pid) - switches0
    finally:
        floor.close()
        wake_percent = wake.close()
    rss = peak_rss_mb(proc.pid)
    stdout, stderr = stop_daemon(op, proc)
    n_msgs, span_s = log_statistics(log)
    lat = np.array(latencies.values) if latencies.values else np.array([np.nan])
    hold, after = latency_split(log, latencies.arrivals)
    result = {
        "bench": "daemon",
        "services_off": sorted(args.without),
        "seconds": round(elapsed, 1),
        "exit_code": proc.returncode,
        "cpu_percent_daemon": round(100.0 * cpu / elapsed, 1),
        "cpu_percent_fakes": round(100.0 * fcpu / elapsed, 1),
        "cpu_percent_threads": threads,
        "peak_rss_mb_daemon": round(rss, 1),
        "pose_latency_ms_p50": round(float(np.percentile(lat, 50)), 2),
        "pose_latency_ms_p99": round(float(np.percentile(lat, 99)), 2),
        "pose_hold_ms_p50": percentile(hold, 50),
        "pose_hold_ms_p99": percentile(hold, 99),
        "pose_after_release_ms_p50": percentile(after, 50),
        "pose_after_release_ms_p99": percentile(after, 99),
        "transport_ms_p50": percentile(floor.values[10:], 50),
        "transport_ms_p99": percentile(floor.values[10:], 99),
        "wake_floor_percent": round(wake_percent, 2),
        "wake_floor_hz": WAKE_FLOOR_HZ,
        "daemon_wakeups_per_s": round(switches / elapsed, 1),
        "poses_received": len(latencies.values),
        "mcap_messages": n_msgs,
        "mcap_messages_per_s": round(n_msgs / span_s, 1) if span_s > 0 else 0.0,
        "mcap_bytes": log.stat().st_size,
        "dropped": dropped_messages(stdout),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    if stderr.strip():
        print(stderr.strip()[-1000:], file=sys.stderr)
    if before is not None:
        result["baseline"] = before.result()
    print_table(result)
    if tmp is not None:
        tmp.cleanup()
    # An undefined figure (no samples) is null, not JSON's missing NaN.
    print(json.dumps({k: None if isinstance(v, float) and math.isnan(v) else v
                      for k, v in result.items()}))  # fmt: skip
    return 0 if proc.returncode == 0 else 1


class Baseline:
    """The old checkout's own bench/daemon.py, run in a thread at the same time as this
    one (both daemons share the machine's load), with the same options."""

    def __init__(self, args: argparse.Namespace) -> None:
        opts = ["--seconds", str(args.seconds)]
        for name in args.without:
            opts += ["--without", name]
        self._out: dict = {}
        self._thread = threading.Thread(
            target=self._run, args=(args.baseline, opts), name="baseline", daemon=True
        )
        self._thread.start()

    def _run(self, checkout: Path, opts: list[str]) -> None:
        try:
            self._out = run_baseline(checkout, "bench/daemon.py", *opts)
        except SystemExit as exc:  # (run_baseline's way of saying it failed)
            self._out = {"error": str(exc)[-500:]}

    def result(self) -> dict:
        self._thread.join()
        return self._out


def print_table(r: dict) -> None:
    """The run's figures as a table (the JSON line follows); with a baseline, its
    figures in a first column."""
    b = r.get("baseline")
    if b is not None and "error" in b:
        print(f"baseline: {b['error']}", file=sys.stderr)
        b = None
    if b is not None:
        b = {**b, "cpu_percent_threads": b.get("cpu_percent_threads") or {}}
    rows = _rows(r)
    width = max(len(k) for k, _ in rows)
    if b is None:
        print(f"{'figure':<{width}}  value")
        for k, v in rows:
            print(f"{k:<{width}}  {v}")
        return
    old = dict(_rows(b))
    print(f"{'figure':<{width}}  {'baseline':>16}  {'this checkout':>16}")
    for k, v in rows:
        print(f"{k:<{width}}  {old.get(k, '-')!s:>16}  {v!s:>16}")


def _rows(r: dict) -> list[tuple[str, object]]:
    """(figure, value) of one run's result, in the table's order."""
    rows = [
        ("daemon CPU, % of one core", r["cpu_percent_daemon"]),
        *((f"  thread {k}", v) for k, v in r["cpu_percent_threads"].items()),
        ("wake-ups per s (daemon) / wake floor %", f"{r['daemon_wakeups_per_s']} / {r['wake_floor_percent']}"),
        ("fakes CPU %", r["cpu_percent_fakes"]),
        ("peak RSS MiB", r["peak_rss_mb_daemon"]),
        ("pose latency p50 / p99 ms", f"{r['pose_latency_ms_p50']} / {r['pose_latency_ms_p99']}"),
        ("  transport floor p50 / p99 ms", f"{r['transport_ms_p50']} / {r['transport_ms_p99']}"),
        ("MCAP messages per s", r["mcap_messages_per_s"]),
        ("dropped", r["dropped"]),
        ("load (1 min)", r["load_average_1min"]),
    ]  # fmt: skip
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
