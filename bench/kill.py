"""A daemon killed with SIGKILL: do the wheels stop, and does anything it started live on?

Two measurements, each over N runs, on the emulated robot with real processes, ptys and
Zenoh on loopback:

- **wheels**: `hilnav fake` runs on its own (publishing the world's truth on Zenoh),
  `hilnav run` drives it at 0.4 m/s from an operator's cmd_vel stream, and is SIGKILLed;
  the time from the kill until the true wheel speed is zero is what the Pioneer's own
  watchdog gives (nothing of hilnav is left to stop it).
- **orphans**: `hilnav run` in simulation (its fake devices are its child) is SIGKILLed;
  counted: runs whose child process is still alive 3 s later.

Prints a table and, on its last line, one JSON object.

    python bench/kill.py [--runs 10]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.daemon import children
from hilnav.bus import Bus, ZenohSettings, free_tcp_port
from msgs import GroundTruth, VelocityCommand

HILNAV = [sys.executable, "-m", "hilnav"]


def _wait(cond, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return False


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return not f.read().split(") ", 1)[1].startswith("Z")
    except FileNotFoundError:
        return False


def _robot_config(tmp: Path, ports: dict[str, str], zport: int) -> Path:
    cfg = tmp / "r1.toml"
    cfg.write_text(
        'name = "r1"\nfleet = ["operator"]\n'
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{zport}"]\n[log]\nenabled = false\n'
        "[services.mapping]\nenabled = false\n[cmd_vel]\ntimeout_s = 1.0\n"
        f'[devices.arcos]\nport = "{ports["arcos"]}"\n'
        f'[devices.ir]\nlink = "serial"\nport = "{ports["ir"]}"\n'
        f'[devices.gyro]\nport = "{ports["gyro"]}"\n[devices.gps]\nport = "{ports["gps"]}"\n'
    )
    return cfg


def wheels_after_kill(tmp: Path) -> float:
    """Seconds from SIGKILL of the daemon to the emulated wheels at rest (inf: never)."""
    truth_port, zport = free_tcp_port(), free_tcp_port()
    op = Bus("operator", ZenohSettings.loopback(truth_port), fleet=["r1"])
    last: list[GroundTruth] = []
    op.subscribe("r1", "truth", lambda r, m: last.append(m))
    fake = subprocess.Popen(
        [*HILNAV, "fake", "--link-dir", str(tmp / "ports"), "--zenoh-connect",
         f"tcp/127.0.0.1:{truth_port}", "--truth-rate", "50"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    daemon = None
    try:
        assert fake.stdout is not None
        ports = json.loads(fake.stdout.readline())
        cfg = _robot_config(tmp, ports, zport)
        daemon = subprocess.Popen([*HILNAV, "run", "--config", str(cfg), "--quiet"],
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)  # fmt: skip
        assert daemon.stdout is not None and " up" in daemon.stdout.readline()
        drv = Bus("operator", ZenohSettings.loopback(connect_ports=[zport]), fleet=["r1"])
        try:
            end = time.monotonic() + 8.0
            while time.monotonic() < end and not (last and last[-1].linear_mps > 0.35):
                drv.publish_to("r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.4, 0.0,
                                                                source="operator"))  # fmt: skip
                time.sleep(0.1)
            drv.publish_to("r1", "cmd_vel", VelocityCommand(time.time_ns(), 0.4, 0.0,
                                                            source="operator"))  # fmt: skip
            speed = last[-1].linear_mps if last else 0.0
            if speed < 0.35:
                raise RuntimeError(f"the robot did not reach speed (true speed {speed:.2f} m/s)")
            killed = time.monotonic()
            daemon.send_signal(signal.SIGKILL)
            daemon.wait(10)
            stopped = _wait(lambda: last and abs(last[-1].linear_mps) < 1e-6, 10.0)
            return time.monotonic() - killed if stopped else float("inf")
        finally:
            drv.close()
    finally:
        for p in (daemon, fake):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait(10)
            if p is not None and p.stdout is not None:
                p.stdout.close()
        op.close()


def orphan_after_kill(tmp: Path) -> bool:
    """True if the daemon's fake-devices child outlived a SIGKILL of the daemon by 3 s."""
    cfg = tmp / "sim.toml"
    cfg.write_text(
        f'name = "r1"\n[zenoh]\nlisten = ["tcp/127.0.0.1:{free_tcp_port()}"]\n'
        "[log]\nenabled = false\n[services.mapping]\nenabled = false\n"
    )
    proc = subprocess.Popen([*HILNAV, "run", "--config", str(cfg), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)  # fmt: skip
    try:
        assert proc.stdout is not None and " up" in proc.stdout.readline()
        kids = children(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        time.sleep(3.0)
        left = [k for k in kids if _alive(k)]
        for k in left:
            os.kill(k, signal.SIGKILL)
        return bool(left)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        if proc.stdout is not None:
            proc.stdout.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    args = ap.parse_args()
    stops: list[float] = []
    orphans = 0
    with tempfile.TemporaryDirectory(prefix="hilnav-kill-") as tmpdir:
        for i in range(args.runs):
            run = Path(tmpdir) / f"run{i}"
            run.mkdir()
            stops.append(wheels_after_kill(run))
            orphans += orphan_after_kill(run)
            print(f"run {i + 1}: wheels at rest {stops[-1]:.2f} s after SIGKILL", flush=True)
    s = sorted(stops)
    res = {
        "bench": "kill",
        "runs": args.runs,
        "wheels_stop_s_median": round(s[len(s) // 2], 3),
        "wheels_stop_s_max": round(s[-1], 3),
        "runs_stopped_within_2s": sum(x <= 2.0 for x in s),
        "orphans": orphans,
    }
    print(f"wheels at rest after SIGKILL: median {res['wheels_stop_s_median']} s, max "
          f"{res['wheels_stop_s_max']} s; orphans {orphans}/{args.runs}")  # fmt: skip
    print(json.dumps(res))


if __name__ == "__main__":
    main()
