"""One robot of ``hilnav fleet``: its own process, devices, localizers, bus and log.

Run by the fleet command as ``python -m hilnav.fleet.robot --index I ...``. The robot

- opens its Zenoh bus (``hilnav.bus.Bus``): listens on its own ``tcp/127.0.0.1`` port,
  connects to the robots started before it, multicast and gossip scouting off, and only
  accepts samples from the fleet's robots; declares ``hilnav/<robot>/alive`` and watches
  the others' tokens;
- rebuilds the deterministic scenario world (fakes.world.paper_scenario, same seed in
  every process) and simulates only its own devices' readings from it (encoders, gyro,
  GPS, and the range-bearing sensor that sees the other robots);
- at each step (paced to wall time: sim time = (wall - t0) * rate): feeds its own
  messages to EKF, single CP and multiple CP; publishes odometry, gyro, gps, truth,
  pose (EKF), relative and pose_box; waits a bounded time for the live peers' boxes of
  this step; contracts its multiple-CP box with the peers' latest boxes (widened by the
  speed bound times the stamp difference) and its relative measurements; publishes the
  contracted box;
- drops a peer whose liveliness token disappears and carries on alone;
- logs every message it publishes or receives to its own MCAP file, and at the end
  writes its figures as JSON (``<out>/<robot>.json``).

Protocol with the parent on stdio: the child prints ``READY <robot>`` once its bus is
open, waits (bounded) for ``GO <t0_wall>`` on stdin, runs, prints ``DONE <robot>`` and
keeps its liveliness token until ``STOP`` (bounded), so a robot that finishes first is
not taken for a lost one. It exits on its own if the parent goes away.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import sys
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np

from fakes.world.paper_scenario import paper_robots, simulate
from hilnav.bus import Bus, ZenohSettings
from hilnav.fleet.paper import METHODS, PaperRobot
from msgs import GroundTruth, Pose2D, PoseBox, wrap_angle

try:  # the log helper's writer; mcap directly if it is not there
    from hilnav.log.writer import LogWriter
except ImportError:  # pragma: no cover
    LogWriter = None  # type: ignore[assignment,misc]


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
    p.add_argument("--go-timeout", type=float, default=60.0)
    return p.parse_args(argv)


class _Inbox:
    """Peer boxes and liveliness changes from Zenoh's threads, drained by the main loop."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.boxes: deque[PoseBox] = deque()
        self.alive_changes: deque[tuple[str, bool]] = deque()
        self.event = threading.Event()

    def on_box(self, robot: str, msg: PoseBox) -> None:
        with self.lock:
            self.boxes.append(msg)
        self.event.set()

    def on_alive(self, robot: str, alive: bool) -> None:
        with self.lock:
            self.alive_changes.append((robot, alive))
        self.event.set()

    def drain(self) -> tuple[list[PoseBox], list[tuple[str, bool]]]:
        with self.lock:
            b, a = list(self.boxes), list(self.alive_changes)
            self.boxes.clear()
            self.alive_changes.clear()
            self.event.clear()
        return b, a


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


def _wait_go(timeout_s: float) -> float | None:
    parts = _wait_line("GO", timeout_s)
    if parts is None or len(parts) != 2:
        return None
    return float(parts[1])


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    parent = os.getppid()
    specs = paper_robots(args.robots)
    names = [s.name for s in specs]
    me = names[args.index]
    ports = [int(p) for p in args.ports.split(",")]
    sc = simulate(specs, duration_s=args.duration, seed=args.seed)
    robot = PaperRobot(sc, args.index, window=args.window)

    settings = ZenohSettings.loopback(
        listen_port=ports[args.index], connect_ports=ports[: args.index]
    )
    bus = Bus(me, settings, fleet=names)
    inbox = _Inbox()
    args.out.mkdir(parents=True, exist_ok=True)
    log = LogWriter(
        args.out / f"{me}.mcap", metadata={"robot": me, "scenario": "paper", "seed": str(args.seed)}
    )
    alive: set[str] = set()
    gone: set[str] = set()  # peers whose token went away: never used again
    dropped: list[dict[str, float | str]] = []
    received = 0
    try:
        bus.subscribe("*", "pose_box", inbox.on_box)
        bus.on_liveliness(inbox.on_alive)
        bus.declare_alive()
        print(f"READY {me}", flush=True)
        t0 = _wait_go(args.go_timeout)
        if t0 is None:
            print(f"{me}: no GO from the parent, exiting", file=sys.stderr)
            return 2
        period = sc.dt / args.rate

        def handle_inbox(now_ns: int) -> None:
            nonlocal received
            boxes, changes = inbox.drain()
            for who, up in changes:
                if who == me:
                    continue
                if up and who not in gone:
                    alive.add(who)
                elif not up and who not in gone:
                    alive.discard(who)
                    gone.add(who)
                    robot.multi.drop_peer(who)
                    dropped.append({"robot": who, "sim_time_s": now_ns * 1e-9})
            for b in boxes:
                if b.robot == me or b.robot in gone:
                    continue
                alive.add(b.robot)
                received += 1
                robot.feed_peer_box(b)
                log.write(f"/{b.robot}/pose_box", b, int(b.stamp_ns))

        for s in range(sc.steps):
            if os.getppid() != parent:
                print(f"{me}: parent gone, exiting", file=sys.stderr)
                return 3
            due = t0 + s * period
            delay = due - time.time()
            if delay > 0:
                time.sleep(min(delay, 5.0))
            st = int(sc.stamps_ns[s])
            handle_inbox(st)
            own = robot.own_messages(s)
            robot.feed_own(own)
            box = robot.box()
            t = sc.truth[args.index, s]
            truth = GroundTruth(
                st,
                me,
                Pose2D(float(t[0]), float(t[1]), wrap_angle(float(t[2]))),
            )
            for topic, m in [
                *own,
                ("truth", truth),
                ("pose", robot.ekf.estimate()),
                ("pose_box", box),
            ]:
                bus.publish(topic, m)
                log.write(f"/{me}/{topic}", m, st)
            # Wait (bounded) for this step's boxes of the live peers.
            deadline = time.monotonic() + args.wait_peers_s * period
            have: set[str] = set()
            while alive and not alive <= have and time.monotonic() < deadline:
                inbox.event.wait(max(0.0, deadline - time.monotonic()))
                handle_inbox(st)
                have = {p for p, b in robot.multi.peers.items() if b.stamp_ns >= st}
            targets = [n for n in names if n != me and n in robot.multi.peers]
            rels = robot.relative_messages(s, targets)
            robot.cooperate(rels)
            for m in rels:
                bus.publish("relative", m)
                log.write(f"/{me}/relative", m, st)
            box = robot.box()
            bus.publish("pose_box", box)
            log.write(f"/{me}/pose_box", box, st)
            robot.record(s)
        result = {
            "robot": me,
            "steps": sc.steps,
            "dt": sc.dt,
            "dropped": dropped,
            "peer_boxes_received": received,
        }
        for m in METHODS:
            tr = robot.tracks[m]
            result[f"{m}_area"] = float(np.sum(tr.area_m2)) * sc.dt
            result[f"{m}_contained"] = int(np.sum(tr.contained))
            result[f"{m}_late_areas"] = [float(a) for a in tr.area_m2[len(tr.area_m2) // 2 :]]
        result["integrity_alarms"] = len(robot.monitor.alarms)
        result["bus"] = {
            "published": bus.stats.published,
            "received": bus.stats.received,
            "malformed": bus.stats.malformed,
            "foreign": bus.stats.foreign,
        }
        (args.out / f"{me}.json").write_text(json.dumps(result))
        print(f"DONE {me}", flush=True)
        # Stay alive (token up) until the whole fleet is done, so that finishing early
        # does not look like a lost robot to the others; bounded.
        _wait_line("STOP", args.go_timeout)
        return 0
    finally:
        log.close()
        bus.close()


if __name__ == "__main__":
    sys.exit(main())
