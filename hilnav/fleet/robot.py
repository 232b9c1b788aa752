"""One robot of ``hilnav fleet``: its own process, scenario devices, localizers, bus and log.

Run by the fleet command as ``python -m hilnav.fleet.robot --index I ...``. The robot is
built from the same parts as the daemon: :class:`hilnav.bus.Bus` (its own
``tcp/127.0.0.1`` port, connected to the robots started before it, scouting off, only the
fleet's samples accepted, liveliness token ``hilnav/<robot>/alive``),
:class:`hilnav.log.writer.LogWriter` (one MCAP file, topics as :mod:`hilnav.topics`
names them) and :class:`hilnav.peers.PeerTable` (a peer is dropped when its token goes
or its boxes stop for ``--peer-timeout`` seconds, and admitted again when they return).
Its devices are the scenario's (fakes.world.paper_scenario, same seed in every process):
encoders, gyro, GPS and the range-bearing sensor that sees the other robots; its
localizers are the paper's three (hilnav.fleet.paper: EKF, single CP, multiple CP).

At each step (paced to wall time: sim time = (wall - t0) * rate) it feeds its own
messages to the localizers; publishes odometry, gyro, gps, truth, pose (EKF) and
pose_box; waits a bounded time for the live peers' boxes of this step; contracts its
multiple-CP box with the peers' latest boxes and its relative measurements; publishes the
contracted box. At the end it writes its figures as JSON (``<out>/<robot>.json``).

Protocol with the parent on stdio: the child prints ``READY <robot>`` once its bus is
open, waits (bounded) for ``GO <t0_wall>`` on stdin, runs, prints ``DONE <robot>`` and
keeps its liveliness token until ``STOP`` (bounded), so a robot that finishes first is
not taken for a lost one. It exits when its stdin closes (the parent went away).
"""

from __future__ import annotations

import argparse
import json
import select
import sys
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from fakes.world.paper_scenario import paper_robots, simulate
from hilnav.bus import Bus, ZenohSettings
from hilnav.fleet.paper import METHODS, PaperRobot
from hilnav.log.writer import LogWriter
from hilnav.peers import PeerTable
from hilnav.topics import log_topic
from msgs import GroundTruth, Pose2D, PoseBox, wrap_angle


def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hilnav.fleet.robot")
    p.add_argument("--index", type=int, required=True)
    p.add_argument("--robots", type=int, required=True)
    p.add_argument("--ports", required=True, help="comma-separated listen port of every robot")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=50.0)
    p.add_argument("--rate", type=float, default=1.0, help="sim seconds per wall second")
    p.add_argument("--window", type=int, default=40)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument(
        "--wait-peers-s",
        type=float,
        default=0.5,
        help="max wait for peer boxes per step, as a fraction of the step period",
    )
    p.add_argument("--peer-timeout", type=float, default=1.0, help="drop a peer silent for S s")
    p.add_argument("--go-timeout", type=float, default=60.0)
    return p.parse_args(argv)


class _Inbox:
    """Peer boxes and liveliness changes from Zenoh's threads, drained by the main loop."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.events: deque[tuple[str, Any]] = deque()
        self.event = threading.Event()

    def put(self, robot: str, what: Any) -> None:
        with self.lock:
            self.events.append((robot, what))
        self.event.set()

    def drain(self) -> list[tuple[str, Any]]:
        with self.lock:
            out = list(self.events)
            self.events.clear()
            self.event.clear()
        return out


def _wait_line(word: str, timeout_s: float) -> list[str] | None:
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


class FleetRobot:
    """One scenario robot on the bus (see the module docstring)."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        specs = paper_robots(args.robots)
        self.names = [s.name for s in specs]
        self.me = self.names[args.index]
        ports = [int(p) for p in args.ports.split(",")]
        self.sc = simulate(specs, duration_s=args.duration, seed=args.seed)
        self.robot = PaperRobot(self.sc, args.index, window=args.window)
        settings = ZenohSettings.loopback(
            listen_port=ports[args.index], connect_ports=ports[: args.index]
        )
        self.bus = Bus(self.me, settings, fleet=self.names)
        self.inbox = _Inbox()
        self.peers = PeerTable(args.peer_timeout)
        self.dropped: list[dict[str, float | str]] = []
        self.received = 0
        args.out.mkdir(parents=True, exist_ok=True)
        meta = {"robot": self.me, "scenario": "paper", "seed": str(args.seed)}
        self.log = LogWriter(args.out / f"{self.me}.mcap", metadata=meta)

    def open(self) -> None:
        self.bus.subscribe("*", "pose_box", lambda r, m: self.inbox.put(r, m))
        self.bus.on_liveliness(lambda r, alive: self.inbox.put(r, alive))
        self.bus.declare_alive()

    def close(self) -> None:
        self.log.close()
        self.bus.close()

    def _publish(self, topic: str, msg: Any, stamp_ns: int) -> None:
        self.bus.publish(topic, msg)
        self.log.write(log_topic(self.me, topic), msg, stamp_ns)

    def _drop(self, who: str, sim_ns: int) -> None:
        self.robot.multi.drop_peer(who)
        self.dropped.append({"robot": who, "sim_time_s": sim_ns * 1e-9})

    def handle_inbox(self, sim_ns: int) -> None:
        """Peer boxes and liveliness changes that arrived; drop silent peers."""
        now = time.monotonic()
        for who, what in self.inbox.drain():
            if who == self.me:
                continue
            if isinstance(what, bool):
                if self.peers.token(who, what, now):
                    self._drop(who, sim_ns)
                continue
            box: PoseBox = what
            self.peers.seen(who, now)
            self.received += 1
            self.robot.feed_peer_box(box)
            self.log.write(log_topic(who, "pose_box"), box, int(box.stamp_ns))
        for who in self.peers.expire(now):
            self._drop(who, sim_ns)

    def step(self, s: int, period: float) -> None:
        st = int(self.sc.stamps_ns[s])
        self.handle_inbox(st)
        own = self.robot.own_messages(s)
        self.robot.feed_own(own)
        t = self.sc.truth[self.args.index, s]
        truth = GroundTruth(st, self.me, Pose2D(float(t[0]), float(t[1]), wrap_angle(float(t[2]))))
        for topic, m in [
            *own,
            ("truth", truth),
            ("pose", self.robot.ekf.estimate()),
            ("pose_box", self.robot.box()),
        ]:
            self._publish(topic, m, st)
        self._wait_for_peers(st, self.args.wait_peers_s * period)
        targets = [n for n in self.names if n != self.me and n in self.robot.multi.peers]
        rels = self.robot.relative_messages(s, targets)
        self.robot.cooperate(rels)
        for m in rels:
            self._publish("relative", m, st)
        self._publish("pose_box", self.robot.box(), st)
        self.robot.record(s)

    def _wait_for_peers(self, st: int, wait_s: float) -> None:
        """Wait (bounded) for this step's boxes of the live peers."""
        deadline = time.monotonic() + wait_s
        have: set[str] = set()
        while self.peers.alive and not self.peers.alive <= have and time.monotonic() < deadline:
            self.inbox.event.wait(max(0.0, deadline - time.monotonic()))
            self.handle_inbox(st)
            have = {p for p, b in self.robot.multi.peers.items() if b.stamp_ns >= st}

    def result(self) -> dict[str, Any]:
        sc, robot = self.sc, self.robot
        out: dict[str, Any] = {
            "robot": self.me,
            "steps": sc.steps,
            "dt": sc.dt,
            "dropped": self.dropped,
            "peer_boxes_received": self.received,
        }
        for m in METHODS:
            tr = robot.tracks[m]
            out[f"{m}_area"] = float(np.sum(tr.area_m2)) * sc.dt
            out[f"{m}_contained"] = int(np.sum(tr.contained))
            out[f"{m}_late_areas"] = [float(a) for a in tr.area_m2[len(tr.area_m2) // 2 :]]
        out["integrity_alarms"] = len(robot.monitor.alarms)
        b = self.bus.stats
        out["bus"] = {
            "published": b.published,
            "received": b.received,
            "malformed": b.malformed,
            "foreign": b.foreign,
        }
        return out


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    fr = FleetRobot(args)
    try:
        fr.open()
        print(f"READY {fr.me}", flush=True)
        parts = _wait_line("GO", args.go_timeout)
        if parts is None or len(parts) != 2:
            print(f"{fr.me}: no GO from the parent, exiting", file=sys.stderr)
            return 2
        t0 = float(parts[1])
        period = fr.sc.dt / args.rate
        for s in range(fr.sc.steps):
            if select.select([sys.stdin], [], [], 0)[0] and not sys.stdin.readline():
                print(f"{fr.me}: parent gone, exiting", file=sys.stderr)
                return 3
            delay = t0 + s * period - time.time()
            if delay > 0:
                time.sleep(min(delay, 5.0))
            fr.step(s, period)
        (args.out / f"{fr.me}.json").write_text(json.dumps(fr.result()))
        print(f"DONE {fr.me}", flush=True)
        # Stay alive (token up) until the whole fleet is done, so that finishing early
        # does not look like a lost robot to the others; bounded.
        _wait_line("STOP", args.go_timeout)
        return 0
    finally:
        fr.close()


if __name__ == "__main__":
    sys.exit(main())
