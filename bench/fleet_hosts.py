"""Benchmark: a fleet across hosts, network namespaces standing in for the hosts, meeting
only through two Zenoh routers; one router is killed mid-run.

Needs root (``ip netns``). The bench makes, and removes at the end (also on SIGINT,
SIGTERM or an error; and, at its start, whatever a previous run left), these namespaces
and links, with the namespaces' own addresses only (10.77.0.0/24; nothing is added to
the root namespace):

    hnf-sw            a bridge, one veth end per other namespace
    hnf-ra, hnf-rb    router A (10.77.0.1) and router B (10.77.0.2): ``hilnav router``,
                      B connected to A
    hnf-h1 .. hnf-h4  the hosts (10.77.0.11 ..): ``hilnav.fleet.host`` processes, their
                      robots shared round-robin, each host's one Zenoh session (its
                      robots') a client of [A, B] listening nowhere

The robots run the paper's scenario on the daemon's runtime (cooperative CP), in real
time. At ``--kill-at`` seconds router A is SIGKILLed; the clients go over to B. The
links are checked while running: every TCP connection of a host namespace goes to a
router. No link impairment is applied (this kernel has no netem; the robots' own
lateness and the routers are the only delays).

Prints a table per robot and, the LAST line, a JSON object: robots, hosts,
realtime_factor (simulated seconds per wall second of the slowest host),
box_containment (robot-steps whose cooperative CP box holds the truth),
box_age_p99_ms (age of a peer's box when the receiver handled it: its arrival wall time
minus the wall time its step was due), peer_loss_detected (robots that saw their peers
go when the router died), seconds_without_peer_after_kill (the longest a robot was
without one of its peers after the kill, until the second router brought it back),
links_only_to_routers, cores (CPU of hosts and router B per wall second), load.

    sudo python bench/fleet_hosts.py [--robots 8] [--duration 20] [--kill-at 10]
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
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hilnav.fleet.launch import ROUTER_READY, Fleet, host_command, router_command, share
from hilnav.fleet.score import percentile, pooled

ROOT = Path(__file__).resolve().parents[1]
PREFIX = "hnf-"
SWITCH = PREFIX + "sw"
ROUTERS = {"ra": "10.77.0.1", "rb": "10.77.0.2"}
PORT = 7447


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def in_ns(ns: str, *cmd: str) -> subprocess.CompletedProcess:
    return ip("netns", "exec", ns, *cmd)


def our_namespaces() -> list[str]:
    out = ip("netns", "list").stdout.split("\n")
    return [line.split()[0] for line in out if line.startswith(PREFIX)]


def remove_namespaces() -> None:
    """Every namespace this bench makes (their veths and the bridge go with them)."""
    for ns in our_namespaces():
        for pid in ip("netns", "pids", ns, check=False).stdout.split():
            try:
                os.kill(int(pid), signal.SIGKILL)
            except (ProcessLookupError, ValueError):
                pass
        ip("netns", "del", ns, check=False)


def make_network(hosts: list[str]) -> dict[str, str]:
    """The switch, the routers' and the hosts' namespaces; name -> address."""
    ip("netns", "add", SWITCH)
    in_ns(SWITCH, "ip", "link", "add", "br0", "type", "bridge")
    in_ns(SWITCH, "ip", "link", "set", "br0", "up")
    in_ns(SWITCH, "ip", "link", "set", "lo", "up")
    addrs = dict(ROUTERS)
    addrs.update({h: f"10.77.0.{11 + i}" for i, h in enumerate(hosts)})
    for name, addr in addrs.items():
        ns = PREFIX + name
        ip("netns", "add", ns)
        # the veth pair is made inside the switch's namespace and one end moved over
        in_ns(SWITCH, "ip", "link", "add", f"s-{name}", "type", "veth", "peer", "name", "eth0")
        in_ns(SWITCH, "ip", "link", "set", "eth0", "netns", ns)
        in_ns(SWITCH, "ip", "link", "set", f"s-{name}", "master", "br0")
        in_ns(SWITCH, "ip", "link", "set", f"s-{name}", "up")
        in_ns(ns, "ip", "addr", "add", f"{addr}/24", "dev", "eth0")
        in_ns(ns, "ip", "link", "set", "eth0", "up")
        in_ns(ns, "ip", "link", "set", "lo", "up")
    return addrs


def links_only_to_routers(hosts: list[str]) -> bool:
    """Every TCP connection of every host namespace goes to a router's port."""
    ok_peers = {f"{a}:{PORT}" for a in ROUTERS.values()}
    seen = False
    for h in hosts:
        out = in_ns(PREFIX + h, "ss", "-Htn").stdout.split("\n")
        for line in out:
            parts = line.split()
            if len(parts) >= 5:
                seen = True
                if parts[4] not in ok_peers:
                    return False
        listening = in_ns(PREFIX + h, "ss", "-Htln").stdout.strip()
        if listening:
            return False  # a robot listens: it could be reached directly
    return seen


def gaps_after(results: list[dict[str, Any]], kill_wall: float, end_wall: float) -> list[float]:
    """Per (robot, peer) dropped after the kill: seconds until it was back."""
    gaps = []
    for r in results:
        down: dict[str, float] = {}
        for t, peer, present, _ in r["peer_events"]:
            if t < kill_wall - 0.05:
                continue
            if not present:
                down.setdefault(peer, t)
            elif peer in down:
                gaps.append(t - down.pop(peer))
        gaps += [end_wall - t for t in down.values()]
    return gaps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=8)
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds")
    ap.add_argument("--kill-at", type=float, default=None, help="kill router A (default: half)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    if os.geteuid() != 0:
        print("fleet_hosts: needs root (ip netns)", file=sys.stderr)
        return 2
    kill_at = args.duration / 2 if args.kill_at is None else args.kill_at
    hosts = [f"h{i + 1}" for i in range(4)]
    names = [f"r{i + 1}" for i in range(args.robots)]
    groups = share(names, len(hosts))
    fleet = Fleet()

    def on_signal(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    remove_namespaces()  # a previous run's, if it was killed hard
    load0 = Path("/proc/loadavg").read_text().split()[:3]
    tmp = tempfile.TemporaryDirectory(prefix="hilnav-fleet-hosts-")
    out = Path(tmp.name)
    try:
        addrs = make_network(hosts)
        eps = {r: f"tcp/{addrs[r]}:{PORT}" for r in ROUTERS}
        fleet.start("ra", "router", router_command([eps["ra"]]), prefix=_ns("ra"),
                    ready=ROUTER_READY, cwd=str(ROOT))  # fmt: skip
        fleet.start("rb", "router", router_command([eps["rb"]], [eps["ra"]]), prefix=_ns("rb"),
                    ready=ROUTER_READY, cwd=str(ROOT))  # fmt: skip
        zs = {"mode": "client", "connect": [eps["ra"], eps["rb"]], "listen": []}
        opts = dict(scenario="paper", robots=args.robots, seed=args.seed, duration=args.duration,
                    rate=1.0, out=out)  # fmt: skip
        for h, members in zip(hosts, groups, strict=False):
            fleet.spawn(h, "host", host_command(h, members, zs, **opts), prefix=_ns(h),
                        members=members, cwd=str(ROOT))  # fmt: skip
        for c in fleet.hosts:
            fleet.wait_ready(c, f"READY {c.name}")
        used = [c.name for c in fleet.hosts]
        t0 = time.time() + 0.5
        fleet.go(t0)
        time.sleep(min(2.0, kill_at / 2))
        only_routers = links_only_to_routers(used)
        fleet.supervise([("ra", kill_at)], t0, t0 + 10 * args.duration + 60,
                        say=lambda m: print(m, flush=True))  # fmt: skip
        cpu = fleet.cpu_s()
        kill_wall = next(c.killed_at for c in fleet.routers if c.name == "ra") or t0 + kill_at
        fleet.finish()
    finally:
        fleet.reap()
        remove_namespaces()
    end_wall = t0 + args.duration
    results = [
        json.loads((out / f"{n}.json").read_text()) for n in names if (out / f"{n}.json").exists()
    ]
    host_files = [json.loads(f.read_text()) for f in out.glob("host-*.json")]
    tmp.cleanup()
    print(
        f"{'robot':6s} {'contained':>10s} {'peer boxes':>10s} {'age p99 ms':>10s} {'lost peers':>10s}"
    )
    for r in results:
        lost = sorted({e[1] for e in r["peer_events"] if not e[2]})
        print(f"{r['robot']:6s} {r['multi_cp_contained']:>5d}/{r['steps']:<4d} {r['peer_boxes_received']:10d} "
              f"{percentile(r['box_age_ms'], 99):10.1f} {len(lost):10d}")  # fmt: skip
    gaps = gaps_after(results, kill_wall, end_wall)
    detected = sum(
        any(not e[2] and e[0] >= kill_wall - 0.05 for e in r["peer_events"]) for r in results
    )
    wall = max((h["wall_s"] for h in host_files), default=0.0)
    sim = max((h["sim_s"] for h in host_files), default=0.0)
    res = {
        "robots": len(results),
        "hosts": len(host_files),
        "routers": 2,
        "realtime_factor": round(sim / wall, 3) if wall else 0.0,
        "box_containment": pooled(results, ["multi_cp"]).get("multi_cp_containment"),
        "box_age_p99_ms": round(percentile([a for r in results for a in r["box_age_ms"]], 99), 1),
        "peer_loss_detected": detected,
        "seconds_without_peer_after_kill": round(max(gaps), 3) if gaps else None,
        "links_only_to_routers": only_routers,
        "cores": round((sum(h["cpu_s"] for h in host_files) + cpu.get("rb", 0.0)) / wall, 2) if wall else None,
        "max_lag_s": max((h["max_lag_s"] for h in host_files), default=None),
        "load_before": [float(v) for v in load0],
        "load_after": [float(v) for v in Path("/proc/loadavg").read_text().split()[:3]],
    }  # fmt: skip
    print(json.dumps(res))
    return 0 if len(results) == args.robots else 1


def _ns(name: str) -> list[str]:
    return ["ip", "netns", "exec", PREFIX + name]


if __name__ == "__main__":
    sys.exit(main())
