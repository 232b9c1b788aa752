"""``hilnav fleet --robots N --scenario paper``: cooperative CP localization as N robot
processes on loopback Zenoh (ekf-vs-cp.txt §2.4, run as real robots would).

Each robot is its own process (``hilnav.fleet.robot``) with its own simulated devices,
localizers (EKF, single CP, multiple CP), Zenoh bus (explicit ``tcp/127.0.0.1`` ports,
multicast scouting off) and MCAP log (``<out>/<robot>.mcap``). The robots discover each
other through liveliness tokens, use the others' latest pose boxes with their stamps and
carry on alone when a peer disappears (``--kill r3@2.0`` kills robot r3's process
2 s of wall time after the start, to see it). The command prints one line per robot and,
last, the same JSON object as bench/cooperative_cp.py (areas summed over the surviving
robots, containment pooled), plus the peers each robot dropped.

Every child is started with a bounded wait for its READY line and killed if it is still
running after the run's deadline; all are reaped before the command returns.
"""

from __future__ import annotations

import argparse
import json
import select
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from hilnav.errors import CliError

METHODS = ("ekf", "single_cp", "multi_cp")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fleet",
        help="run N robots as processes on loopback Zenoh (cooperative CP)",
        description="Cooperative CP localization as N robot processes on loopback Zenoh: each "
        "robot simulates its own devices from the paper's scenario, runs the EKF, single CP "
        "and multiple CP, exchanges pose boxes with the others, and logs to <out>/<robot>.mcap. "
        "A peer whose token goes or whose boxes stop for 1 s is dropped until it returns. "
        "Prints one line per robot and, last, a JSON summary.",
    )
    p.add_argument("--robots", type=int, default=3, help="number of robots (paper: 3)")
    p.add_argument(
        "--scenario", default="paper", choices=["paper"], help="the ekf-vs-cp experiment (§2.4)"
    )
    p.add_argument("--duration", type=float, default=50.0, help="simulated seconds")
    p.add_argument("--rate", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--seed", type=int, default=1, help="seed of the scenario's errors")
    p.add_argument("--window", type=int, default=40, help="CP sliding window (steps)")
    p.add_argument(
        "--out", type=Path, default=None, help="directory for the MCAP logs (default: a temp dir)"
    )
    p.add_argument(
        "--kill",
        action="append",
        default=[],
        metavar="ROBOT@SECONDS",
        help="kill a robot's process after SECONDS of wall time",
    )
    p.set_defaults(func=run)


def _parse_kills(items: list[str], names: list[str]) -> list[tuple[str, float]]:
    out = []
    for it in items:
        name, _, t = it.partition("@")
        try:
            sec = float(t)
        except ValueError:
            raise CliError(f"--kill {it!r}: use ROBOT@SECONDS, e.g. r3@2.0") from None
        if name not in names:
            raise CliError(f"--kill {it!r}: no robot {name!r}; robots are {', '.join(names)}")
        out.append((name, sec))
    return out


def _read_line(proc: subprocess.Popen, timeout_s: float) -> str | None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        r, _, _ = select.select([proc.stdout], [], [], 0.2)
        if r:
            line = proc.stdout.readline()
            return line.decode().strip() if line else None
        if proc.poll() is not None:
            return None
    return None


def summarize(results: list[dict], dt: float) -> dict:
    """The benchmark's JSON from the robots' result files."""
    import numpy as np

    out: dict = {}
    for m in METHODS:
        out[f"{m}_area"] = round(sum(r[f"{m}_area"] for r in results), 4)
        steps = sum(r["steps"] for r in results)
        out[f"{m}_containment"] = (
            round(sum(r[f"{m}_contained"] for r in results) / steps, 4) if steps else 0.0
        )
        late = [a for r in results for a in r[f"{m}_late_areas"]]
        out[f"{m}_late_mean_area_m2"] = round(float(np.mean(late)), 5) if late else 0.0
    if out["ekf_area"]:
        out["multi_over_ekf_area"] = round(out["multi_cp_area"] / out["ekf_area"], 4)
    out["integrity_alarms"] = sum(r["integrity_alarms"] for r in results)
    return out


def run(args: argparse.Namespace) -> int:
    from fakes.world.paper_scenario import paper_robots
    from hilnav.bus import free_tcp_port

    if args.robots < 1 or args.robots > 12:
        raise CliError(f"--robots {args.robots}: use 1 to 12")
    if args.rate <= 0 or args.duration <= 0:
        raise CliError("--rate and --duration must be > 0")
    names = [s.name for s in paper_robots(args.robots)]
    kills = _parse_kills(args.kill, names)
    out = (args.out or Path(tempfile.mkdtemp(prefix="hilnav-fleet-"))).resolve()
    out.mkdir(parents=True, exist_ok=True)
    ports = [free_tcp_port() for _ in names]
    procs: dict[str, subprocess.Popen] = {}
    wall = args.duration / args.rate
    try:
        for i, name in enumerate(names):
            procs[name] = _start_robot(args, i, name, ports, out)
        t0 = time.time() + 0.5
        for p in procs.values():
            p.stdin.write(f"GO {t0!r}\n".encode())
            p.stdin.flush()
        print(f"fleet: {len(names)} robots on ports {ports}, logs in {out}", flush=True)
        deadline = t0 + wall + 30.0 + 0.05 * args.duration * len(names)
        _supervise(procs, kills, t0, deadline)
        _finish(procs)
    finally:
        _reap(procs)
    results = _results(names, procs, out)
    res = summarize(results, 0.1)
    res["robots"] = [r["robot"] for r in results]
    res["dropped"] = {r["robot"]: [d["robot"] for d in r["dropped"]] for r in results}
    res["logs"] = sorted(str(p) for p in out.glob("*.mcap"))
    res["steps_per_second"] = round(sum(r["steps"] for r in results) / max(wall, 1e-9), 1)
    print(json.dumps(res))
    return 0


def _start_robot(
    args: argparse.Namespace, i: int, name: str, ports: list[int], out: Path
) -> subprocess.Popen:
    cmd = [
        sys.executable, "-m", "hilnav.fleet.robot",
        "--index", str(i), "--robots", str(args.robots),
        "--ports", ",".join(map(str, ports)), "--seed", str(args.seed),
        "--duration", str(args.duration), "--rate", str(args.rate),
        "--window", str(args.window), "--out", str(out),
    ]  # fmt: skip
    p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    line = _read_line(p, 60.0)
    if line != f"READY {name}":
        p.kill()
        p.wait(10)
        raise CliError(f"robot {name} did not start (got {line!r}); see its stderr above")
    return p


def _supervise(
    procs: dict[str, subprocess.Popen], kills: list[tuple[str, float]], t0: float, deadline: float
) -> None:
    """Until every robot is done (or the deadline): carry out the --kill schedule."""
    pending = sorted(kills, key=lambda k: k[1])
    done: set[str] = set()
    while time.time() < deadline:
        running = {n: p for n, p in procs.items() if p.poll() is None and n not in done}
        if not running:
            break
        now = time.time() - t0
        while pending and now >= pending[0][1]:
            victim, _ = pending.pop(0)
            if procs[victim].poll() is None:
                procs[victim].send_signal(signal.SIGKILL)
                print(f"fleet: killed {victim} at {now:.1f} s", flush=True)
        ready, _, _ = select.select([p.stdout for p in running.values()], [], [], 0.05)
        for n, p in running.items():
            if p.stdout in ready:
                line = p.stdout.readline().decode().strip()
                if line == f"DONE {n}" or not line:
                    done.add(n)


def _finish(procs: dict[str, subprocess.Popen]) -> None:
    """Everyone finished (or died): tell them to close, and wait (bounded)."""
    for p in procs.values():
        if p.poll() is None:
            try:
                p.stdin.write(b"STOP\n")
                p.stdin.flush()
            except OSError:
                pass
    for p in procs.values():
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            p.kill()


def _reap(procs: dict[str, subprocess.Popen]) -> None:
    for p in procs.values():
        if p.poll() is None:
            p.kill()
    for p in procs.values():
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
        for f in (p.stdin, p.stdout):
            if f:
                f.close()


def _results(names: list[str], procs: dict[str, subprocess.Popen], out: Path) -> list[dict]:
    results = []
    for name in names:
        f = out / f"{name}.json"
        if not f.is_file():
            print(f"{name}: no result (killed or failed, exit {procs[name].returncode})")
            continue
        r = json.loads(f.read_text())
        results.append(r)
        drops = ", ".join(f"{d['robot']}@{d['sim_time_s']:.1f}s" for d in r["dropped"]) or "none"
        print(
            f"{name}: multi CP area {r['multi_cp_area']:.2f} m^2 s, contained "
            f"{r['multi_cp_contained']}/{r['steps']}, peer boxes {r['peer_boxes_received']}, "
            f"dropped {drops}"
        )
    if not results:
        raise CliError("no robot finished; nothing to report")
    return results
