"""One robot of ``hilnav fleet``: a :class:`hilnav.runtime.RobotRuntime` (the daemon's
runtime: pipeline, peers, bus, log) fed by a scenario's devices instead of drivers.

A host process (:mod:`hilnav.fleet.host`) steps its robots together. Per step ``s``:

1. :meth:`SimRobot.begin_step`: the peers' boxes and liveliness changes that arrived are
   handled; the robot's device messages of the step go through its queue as one entry,
   like one device read of the daemon (the CP service steps and publishes the step's
   ``pose_box``); the truth is logged; the reference localizers (if any) are fed the same
   messages;
2. the host waits (bounded) until every live peer's box of this step is in
   (:meth:`SimRobot.peers_ready`);
3. :meth:`SimRobot.end_step`: the range-bearing scan of the live peers goes through the
   queue (``relative``: the CP service contracts the box with the peers' latest boxes);
   the box is scored against the truth.

Each peer box's age when it is handled (wall time received minus the wall time its step
was due) is kept, and each peer admitted or dropped, with the wall time of its cause.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from drivers.clock import now_ns
from hilnav.bus import ZenohSettings
from hilnav.bus_session import BusSession
from hilnav.config import RobotConfig
from hilnav.fleet.scenarios import FleetScenario, Reference, RobotDevices
from hilnav.fleet.score import Track
from hilnav.log.encoding import ViewMemo
from hilnav.runtime import Item, RobotRuntime
from hilnav.topics import log_topic
from msgs import GroundTruth, Pose2D, wrap_angle


class SimRobot:
    """One scenario robot on the bus (see the module docstring)."""

    def __init__(
        self,
        scenario: FleetScenario,
        name: str,
        base: RobotConfig,
        zenoh: ZenohSettings,
        *,
        out: Path | None,
        wake: threading.Event | None = None,
        reference: bool = True,
        shared: BusSession | None = None,
        memo: ViewMemo | None = None,
    ) -> None:
        """``shared``, ``memo``: the host's Zenoh session and log views, shared by its
        robots (None: a session of the robot's own)."""
        self.scenario, self.name = scenario, name
        self.cfg = scenario.config(name, base)
        if not self.cfg.services.localization.enabled:
            raise ValueError(f"{name}: the fleet needs services.localization.enabled = true")
        self.shared, self.memo = shared, memo
        self.rt = self.make_runtime(zenoh, wake)
        self.out = out
        self.want_reference = reference
        self.devices: RobotDevices | None = None
        self.reference: Reference | None = None
        self.multi = Track()
        self.ages_ms: list[float] = []
        self.steps = 0
        self._base_ns = 0
        self._rate = 1.0
        self._stamp_ns = 0

    def make_runtime(self, zenoh: ZenohSettings, wake: threading.Event | None) -> RobotRuntime:
        """The robot's runtime (a scenario's robot class may give it another pipeline)."""
        return RobotRuntime(
            self.cfg, zenoh=zenoh, prog=f"hilnav fleet: {self.name}", wake=wake, memo=self.memo
        )

    @property
    def cp(self) -> Any:
        loc = self.rt.pipeline.localization
        assert loc is not None
        return loc.cp

    def open(self, metadata: dict[str, str] | None = None) -> None:
        """The Zenoh session, the log, the peers' subscriptions and the liveliness token."""
        rt = self.rt
        rt.open_bus(self.shared)
        if self.out is not None:
            rt.open_log(self.out / f"{self.name}.mcap", simulated=True, metadata=metadata)
        rt.declare_peers()
        assert rt.bus is not None
        rt.bus.declare_alive()

    def start(self, base_ns: int, rate: float) -> None:
        """Stamps are ``base_ns`` + scenario time; the step of scenario time t is due at
        wall time ``base_ns`` + t / ``rate``."""
        self._base_ns, self._rate = int(base_ns), float(rate)
        self.devices = self.scenario.devices(self.name, base_ns)
        if self.want_reference:
            self.reference = self.scenario.reference(self.name, self.cfg, base_ns)

    def due_ns(self, stamp_ns: int) -> int:
        """The wall time a message stamped ``stamp_ns`` was due."""
        return self._base_ns + int((stamp_ns - self._base_ns) / self._rate)

    def pump(self) -> int:
        """Handle what is queued (peer boxes, liveliness: the host's session hands over
        what it received first); drop silent peers."""
        if self.shared is not None:
            self.shared.pump()
        rt, n = self.rt, 0
        while (item := rt.next(0.0)) is not None:
            if type(item) is Item and item.peer and item.topic == "pose_box":
                self.ages_ms.append((item.recv_ns - self.due_ns(item.msg.stamp_ns)) * 1e-6)
            rt.handle(item)
            n += 1
        rt.expire_peers()
        return n

    def feed_step(self, s: int) -> list[tuple[str, Any]]:
        """The device messages of step ``s`` through the queue as one read, handled (the
        peers' boxes that came first too); the messages."""
        assert self.devices is not None
        self.pump()
        msgs = self.devices.messages(s)
        if msgs:
            self.rt.put_read(msgs)
        self.pump()
        return msgs

    def begin_step(self, s: int) -> None:
        assert self.devices is not None
        msgs = self.feed_step(s)
        self._stamp_ns = stamp = int(msgs[0][1].stamp_ns) if msgs else self._stamp_ns
        t = self.devices.truth(s)
        truth = GroundTruth(stamp, self.name, Pose2D(t.x, t.y, wrap_angle(t.theta)))
        self.rt.log_msg(log_topic(self.name, "truth"), truth, now_ns())
        if self.reference is not None:
            self.reference.feed(msgs)

    def peers_ready(self) -> bool:
        """Every live peer's box of this step is in."""
        boxes, st = self.cp.peers, self._stamp_ns
        return all(p in boxes and boxes[p].stamp_ns >= st for p in self.rt.peers.alive)

    def end_step(self, s: int) -> None:
        assert self.devices is not None
        self.pump()
        cp = self.cp
        targets = sorted(p for p in cp.peers if p in self.rt.peers.alive)
        scan = self.devices.relative_scan(s, targets)
        if scan is not None:
            self.rt.put("relative", scan)
            self.pump()
        t = self.devices.truth(s)
        truth = (t.x, t.y, t.theta)
        box = cp.box()  # (its heading next to (-pi, pi]: tracks compare modulo 2 pi)
        bx, by, bt = box.x, box.y, box.theta
        self.multi.record((bx.lo, by.lo, bt.lo), (bx.hi, by.hi, bt.hi), truth)
        if self.reference is not None:
            self.reference.record(truth, box)
        self.steps += 1

    def close(self) -> None:
        self.rt.close()

    def result(self, dt: float) -> dict[str, Any]:
        """This robot's figures (the fleet command pools them)."""
        out = self.runtime_figures(dt)
        out.update({f"multi_cp_{k}": v for k, v in self.multi.figures(dt).items()})
        if self.reference is not None:
            out.update(self.reference.figures(dt))
        return out

    def runtime_figures(self, dt: float) -> dict[str, Any]:
        """What every scenario's robot reports: steps, peers, the peers' boxes and their
        age, the bus, the faults."""
        rt = self.rt
        b = rt.bus.stats if rt.bus is not None else None
        return {
            "robot": self.name,
            "steps": self.steps,
            "dt": dt,
            "peer_events": [
                [round(e.wall_ns * 1e-9, 4), e.robot, e.present, e.why] for e in rt.peer_events
            ],
            "peer_boxes_received": rt.stats.by_topic.get("pose_box", 0),
            "box_age_ms": [round(a, 2) for a in self.ages_ms],
            "bus": {
                "published": b.published if b else 0,
                "received": b.received if b else 0,
                "malformed": b.malformed if b else 0,
                "foreign": b.foreign if b else 0,
            },
            "faults": dict(rt.stats.faults),
            "queue_dropped": rt.stats.dropped,
        }
