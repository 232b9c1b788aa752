"""A host process of ``hilnav fleet``: several robots (:class:`hilnav.fleet.robot.SimRobot`,
each its own runtime and bus) stepped together in real time by one thread.

The robots' buses share the host's ONE Zenoh session
(:class:`hilnav.bus_session.BusSession`, deferred): one subscription per peer topic for
all of them, each peer's sample decoded once, waiting in Zenoh's channel until the
stepping thread looks (no Python callback thread takes the GIL from it); each robot
keeps its own publishers, liveliness token, queryables and log. The log views of a
peer's box, the same in every robot's log, are made once (ViewMemo).

Run as ``python -m hilnav.fleet.host --scenario paper --robots N --members r1,r4 ...``
(the fleet command starts one per share of the robots; bench/fleet_hosts.py starts them
inside network namespaces). Every host rebuilds the same scenario from the same
arguments. Pacing: step ``s`` is due at wall time ``t0 + s * dt / rate``; a host that is
late does not sleep, and says how late it got.

Protocol with the parent on stdio: ``READY <host>`` once the members' buses are open;
then a bounded wait for ``GO <t0_wall>`` on stdin; the run; the members' figures in
``<out>/<robot>.json`` and the host's own (wall and CPU time of the run, how late it
got) in ``<out>/host-<host>.json``; ``DONE <host>``; the liveliness tokens stay up until
``STOP`` (bounded), so a host that finishes first is not taken for a lost one. A host
exits when its stdin closes (the parent went away). ``HILNAV_FLEET_PROFILE=DIR``: the
run under cProfile, timed by the stepping thread's CPU time, in ``DIR/host-<host>.prof``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import select
import sys
import threading
import time
from pathlib import Path

from hilnav.bus import ZenohSettings, zenoh_problem
from hilnav.bus_session import BusSession
from hilnav.config import ConfigError, load_config
from hilnav.fleet.robot import SimRobot
from hilnav.fleet.scenarios import ScenarioArgs, build
from hilnav.log.encoding import ViewMemo
from hilnav.log.foxglove import views_use_state
from hilnav.runtime import StartError
from hilnav.topics import PEER_TOPICS, topic_type

POLL_S = 0.001  # how often a host waiting for its robots' peers looks for their boxes


def parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hilnav.fleet.host")
    p.add_argument("--host", required=True, help="this host's name (for its lines and files)")
    p.add_argument("--scenario", default="paper")
    p.add_argument("--robots", type=int, required=True, help="robots in the whole fleet")
    p.add_argument("--members", required=True, help="comma-separated robots this host runs")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=50.0)
    p.add_argument("--rate", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--window", type=int, default=40)
    p.add_argument("--data", default=None, help="a data set's directory (--scenario mrclam)")
    p.add_argument("--start", type=float, default=0.0, help="seconds of the data set skipped")
    p.add_argument("--config", default=None, help="the robots' base config (TOML)")
    p.add_argument("--zenoh", required=True, help="the robots' ZenohSettings as JSON")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--no-log", action="store_true")
    p.add_argument("--no-reference", action="store_true")
    p.add_argument("--wait-peers", type=float, default=0.5, help="of a step period, at most")
    p.add_argument("--go-timeout", type=float, default=120.0)
    return p.parse_args(argv)


def zenoh_from_json(text: str) -> ZenohSettings:
    d = json.loads(text)
    for k in ("listen", "connect"):
        d[k] = tuple(d.get(k, ()))
    return ZenohSettings(**d)


def wait_line(word: str, timeout_s: float) -> list[str] | None:
    """The first stdin line starting with ``word`` (split), or None on EOF/timeout."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        r, _, _ = select.select([sys.stdin], [], [], 0.5)
        if r:
            line = sys.stdin.readline()
            if not line:
                return None
            parts = line.split()
            if parts and parts[0] == word:
                return parts
    return None


def _parent_gone() -> bool:
    return bool(select.select([sys.stdin], [], [], 0)[0]) and not sys.stdin.readline()


class Host:
    """The host's robots and their stepping (module docstring)."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        sa = ScenarioArgs(
            args.robots, args.duration, args.seed, args.window, args.data or "", args.start
        )
        self.scenario = build(args.scenario, sa)
        robot_class = getattr(self.scenario, "robot_class", SimRobot)
        try:
            base = load_config(args.config)
        except ConfigError as exc:
            raise SystemExit(f"hilnav fleet host {args.host}: {exc}") from None
        self.zenoh = zs = zenoh_from_json(args.zenoh)
        self.wake = threading.Event()
        out = None if args.no_log else args.out
        # the robots' one Zenoh session, opened by open(); their peers' boxes' log views
        self.session: BusSession | None = None
        self.memo = ViewMemo(peer_classes())
        self.robots = [
            robot_class(
                self.scenario, name, base, zs, out=out, wake=self.wake,
                reference=not args.no_reference, memo=self.memo,
            )
            for name in args.members.split(",")
        ]  # fmt: skip
        self.meta = {"scenario": args.scenario, "seed": str(args.seed), "host": args.host}
        self.max_lag_s = 0.0
        self.late_steps = 0
        self.wall_s = self.cpu_s = 0.0

    def open(self) -> None:
        """The host's Zenoh session, then each robot's bus on it, log and token."""
        try:
            self.session = BusSession(self.zenoh, deferred=True)
        except Exception as exc:  # zenoh.ZError and friends
            raise StartError(f"cannot open the Zenoh session: {zenoh_problem(exc)}") from None
        for r in self.robots:
            r.shared = self.session
            r.open(self.meta)

    def close(self) -> None:
        for r in self.robots:
            r.close()
        if self.session is not None:
            self.session.close()

    def run(self, t0: float) -> bool:
        """Every step of the scenario, paced from ``t0``; False if the parent went away."""
        a, sc = self.args, self.scenario
        period = sc.dt_s / a.rate
        for r in self.robots:
            r.start(int(t0 * 1e9), a.rate)
        c0 = _cpu()
        for s in range(sc.steps):
            if _parent_gone():
                return False
            due = t0 + s * period
            delay = due - time.time()
            if delay > 0:
                time.sleep(min(delay, 5.0))
            elif -delay > 0.5 * period:
                self.late_steps += 1
            self.max_lag_s = max(self.max_lag_s, -delay)
            for r in self.robots:
                r.begin_step(s)
            self._wait_for_peers(due + a.wait_peers * period)
            for r in self.robots:
                r.end_step(s)
        self.wall_s = time.time() - t0
        self.cpu_s = _cpu() - c0
        return True

    def _wait_for_peers(self, deadline: float) -> None:
        """Until every robot has its live peers' boxes of this step (or the deadline)."""
        while not all(r.peers_ready() for r in self.robots):
            remaining = deadline - time.time()
            if remaining <= 0:
                return
            # the peers' boxes wait in the session's channel: looked at every POLL_S
            self.wake.wait(min(remaining, POLL_S))
            self.wake.clear()
            for r in self.robots:
                r.pump()

    def write_results(self) -> None:
        a, dt = self.args, self.scenario.dt_s
        a.out.mkdir(parents=True, exist_ok=True)
        for r in self.robots:
            (a.out / f"{r.name}.json").write_text(json.dumps(r.result(dt)))
        host = {
            "host": a.host,
            "robots": [r.name for r in self.robots],
            "wall_s": round(self.wall_s, 3),
            "cpu_s": round(self.cpu_s, 3),
            "max_lag_s": round(self.max_lag_s, 4),
            "late_steps": self.late_steps,
            "steps": self.scenario.steps,
            "sim_s": round((self.scenario.steps - 1) * dt, 3),
        }
        (a.out / f"host-{a.host}.json").write_text(json.dumps(host))


def peer_classes() -> list[type]:
    """The classes of the peers' messages every robot of a host logs, whose log views
    can be shared (hilnav.log.encoding.ViewMemo)."""
    classes = (topic_type(t) for t in PEER_TOPICS)
    return [c for c in classes if c is not None and not views_use_state(c)]


def profiled(host: Host, t0: float) -> bool:
    """``host.run(t0)``; with ``HILNAV_FLEET_PROFILE=DIR`` in the environment, under
    cProfile timed by the stepping thread's CPU time (``DIR/host-<host>.prof``)."""
    where = os.environ.get("HILNAV_FLEET_PROFILE")
    if not where:
        return host.run(t0)
    import cProfile

    prof = cProfile.Profile(time.thread_time)
    try:
        return prof.runcall(host.run, t0)
    finally:
        Path(where).mkdir(parents=True, exist_ok=True)
        prof.dump_stats(Path(where) / f"host-{host.args.host}.prof")


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    host = Host(args)
    try:
        try:
            host.open()
        except StartError as exc:
            print(f"hilnav fleet host {args.host}: {exc}", file=sys.stderr, flush=True)
            return 2
        print(f"READY {args.host}", flush=True)
        parts = wait_line("GO", args.go_timeout)
        if parts is None or len(parts) != 2:
            print(f"host {args.host}: no GO from the parent, exiting", file=sys.stderr)
            return 2
        if not profiled(host, float(parts[1])):
            print(f"host {args.host}: parent gone, exiting", file=sys.stderr)
            return 3
        host.write_results()
        print(f"DONE {args.host}", flush=True)
        wait_line("STOP", args.go_timeout)  # tokens stay up until the whole fleet is done
        return 0
    finally:
        host.close()


if __name__ == "__main__":
    sys.exit(main())
