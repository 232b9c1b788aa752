"""Benchmark: the robot daemon on the emulated devices at their nominal rates.

Starts ``hilnav run`` on the embedded defaults (simulated Pioneer: SIPs at 10 Hz, IR board
at 20 Hz on CAN through the emulated slcan adapter, gyro at 100 Hz, GPS at 1 Hz; every
service on: heading filter, pose EKF, CP localization, IR mapping with sample-based data
association), drives the demo's office tour over cmd_vel from a second Zenoh session for
``--seconds`` (default 60), then stops the daemon with SIGTERM and reads its MCAP log.

Prints, the LAST line a JSON object:
- ``cpu_percent_daemon``: CPU time of the daemon process over the run, in percent of one
  core (``cpu_percent_fakes``: the emulated devices' process, for reference);
- ``pose_latency_ms_p50`` / ``_p99``: from the time the Pioneer's bytes were read (the
  odometry stamp, which the pose inherits) to the pose arriving in the second session;
- ``mcap_messages_per_s``: messages in the log (all topics, raw bytes and Foxglove views
  included) per second of run; ``dropped``: messages the daemon's queues dropped.

    python bench/daemon.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
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

from hilnav.bus import free_tcp_port  # noqa: E402
from hilnav.commands.demo import TOUR, Operator  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def cpu_seconds(pid: int) -> float:
    """utime + stime of one process (not its children), from /proc."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(p) for p in f.read().split()]
    except OSError:
        return []


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the run")
    ap.add_argument("--out", type=Path, default=None, help="keep the log in this directory")
    args = ap.parse_args(argv)
    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory(prefix="hilnav-bench-daemon-")
        out = Path(tmp.name)
    else:
        out = args.out
        out.mkdir(parents=True, exist_ok=True)
    port = free_tcp_port()
    cfg = out / "bench-robot.toml"
    cfg.write_text(
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{port}"]\ngossip_scouting = true\n[log]\ndir = "{out}"\n'
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
    op = Operator("r1", port)
    latencies: list[float] = []
    lock = threading.Lock()

    def on_pose(robot, msg):  # noqa: ANN001
        now = time.time_ns()
        with lock:
            latencies.append((now - msg.stamp_ns) * 1e-6)

    op.bus.subscribe("r1", "pose", on_pose)
    t_wait = time.monotonic() + 60.0
    while time.monotonic() < t_wait and (op.where() is None or not op.alive):
        if proc.poll() is not None:
            print(proc.stderr.read(), file=sys.stderr)
            return 1
        time.sleep(0.1)
    fake_pids = children(proc.pid)
    cpu0 = cpu_seconds(proc.pid)
    fcpu0 = sum(cpu_seconds(p) for p in fake_pids)
    with lock:
        latencies.clear()
    t0 = time.monotonic()
    deadline = t0 + args.seconds
    time.sleep(min(2.0, args.seconds / 4))  # the gyro's bias is learnt at rest
    while time.monotonic() < deadline:
        op.drive(TOUR, 0.5, deadline)
    cpu1 = cpu_seconds(proc.pid)
    fcpu1 = sum(cpu_seconds(p) for p in fake_pids)
    elapsed = time.monotonic() - t0
    op.send(0.0, 0.0)
    op.close()
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    dropped = None
    for line in stdout.splitlines():
        if "dropped" in line:
            dropped = int(line.split(" dropped")[0].rsplit(" ", 1)[1])
    from mcap.reader import make_reader

    with open(log, "rb") as f:
        summary = make_reader(f).get_summary()
    stats = summary.statistics if summary is not None else None
    n_msgs = stats.message_count if stats is not None else 0
    span_s = (stats.message_end_time - stats.message_start_time) * 1e-9 if stats else 0.0
    lat = np.array(latencies) if latencies else np.array([np.nan])
    result = {
        "bench": "daemon",
        "seconds": round(elapsed, 1),
        "exit_code": proc.returncode,
        "cpu_percent_daemon": round(100.0 * (cpu1 - cpu0) / elapsed, 1),
        "cpu_percent_fakes": round(100.0 * (fcpu1 - fcpu0) / elapsed, 1),
        "pose_latency_ms_p50": round(float(np.percentile(lat, 50)), 2),
        "pose_latency_ms_p99": round(float(np.percentile(lat, 99)), 2),
        "poses_received": len(latencies),
        "mcap_messages": n_msgs,
        "mcap_messages_per_s": round(n_msgs / span_s, 1) if span_s > 0 else 0.0,
        "mcap_bytes": log.stat().st_size,
        "dropped": dropped,
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    if stderr.strip():
        print(stderr.strip()[-1000:], file=sys.stderr)
    if tmp is not None:
        tmp.cleanup()
    print(json.dumps(result))
    return 0 if proc.returncode == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
