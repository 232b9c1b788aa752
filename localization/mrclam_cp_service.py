"""Guaranteed (CP) localization of one real robot as a service, message by message (issue 14
items 2-3): the service behind ``hilnav replay`` of an ``hilnav import mrclam`` log and
each robot of ``hilnav fleet --scenario mrclam``. It runs one
:class:`~localization.cp_rb.RangeBearingCP` the way the batch runner
(:func:`localization.mrclam_cp.run_cp`) does, but knows the other robots only by the
messages they publish.

``feed(topic, msg) -> [(topic, msg)]``:

- ``landmark_map`` (msgs.LandmarkMap): the known landmarks (+- ``landmark_sigmas`` of
  their standard deviations);
- ``velocity`` (msgs.VelocityOdometry): the commanded (v, w);
- ``landmark_range_bearing``, ``peer_range_bearing`` (msgs.RangeBearing, this robot's):
  the measurements of one stamp form one camera frame, solved together.

Time is the messages' stamps. A message stamped ``t`` says that everything before ``t``
is in: the ticks and the frame stamped before ``t`` are then handled, in time order (a
tick before a frame of the same instant), each after the commands stamped up to its own
instant, the order of the batch runner. The ticks are every ``tick_s`` from the landmark
map's stamp (the log's start); before the map, only the commands are taken.

``advance(stamp_ns)`` says the same without a message (a clock: the fleet's robots call
it at every step, so that their boxes go out while their odometry pauses).

Outputs:

- ``pose_box`` (msgs.PoseBox) at every tick: the box predicted from the latest solved
  state to the tick (the whole plane before the first solve), with the solver's
  ``status`` and ``alert_stamp_ns`` (when it last weakened its guarantee);
- ``peer_sighting`` (msgs.PeerSighting) for every robot this one measured (cooperative):
  this robot's box at that instant with the measurement, for the seen robot, and the
  pieces the box is the hull of (heading slices with their own position boxes).

``feed_other(robot, topic, msg)`` takes the other robots' ``pose_box`` (their latest
bounded box: what a sighting of them is measured against, aged by its stamp,
``peer_speed_mps``, ``peer_yaw_rate_radps``) and the ``peer_sighting`` meant for this
robot (an observation of itself at its next solve). Alone (``cooperative=False``) robot
measurements are ignored. Skipped and counted (``counts``): messages that go back in
time, measurements before the map or of landmarks not in it, sightings of a robot whose box is not
known yet, sightings this robot cannot send (no box of its own yet) or that would go to a
robot that never published a box (not in the log, not in the fleet).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from typing import Any

from localization.cp_config import RangeBearingCPConfig
from localization.cp_rb import Observation, PeerBox, RangeBearingCP
from localization.cp_rb_sightings import aged_to
from msgs import (
    Interval,
    LandmarkMap,
    PeerSighting,
    PoseBox,
    RangeBearing,
    VelocityOdometry,
)

NS = 1e-9
RANGE_BEARING_TOPICS = ("landmark_range_bearing", "peer_range_bearing")
_DIGITS = re.compile(r"(\d+)$")


def subject_of(name: str, known: dict[str, int]) -> int:
    """A robot's number for naming its observations: the trailing digits of its name
    (MRCLAM's ``r3`` -> 3), else 1000 + the order it was first met in."""
    n = known.get(name)
    if n is None:
        m = _DIGITS.search(name)
        n = int(m.group(1)) if m else 1000 + len(known)
        known[name] = n
    return n


def peer_box(box: PoseBox, pieces: tuple[float, ...] = ()) -> PeerBox:
    """A published box (and a sighting's pieces, 6 numbers each) as the solver takes it
    (seconds). Pieces that are not whole, or not inside the box, are dropped (the box
    alone is then used)."""
    alert = box.alert_stamp_ns * NS if box.alert_stamp_ns > 0 else -math.inf
    hull = (box.x.lo, box.x.hi, box.y.lo, box.y.hi, box.theta.lo, box.theta.hi)
    parts = tuple(tuple(pieces[i : i + 6]) for i in range(0, len(pieces) - len(pieces) % 6, 6))
    if len(pieces) % 6 or not all(
        hull[2 * k] <= p[2 * k] <= p[2 * k + 1] <= hull[2 * k + 1] for p in parts for k in range(3)
    ):
        parts = ()
    return PeerBox(box.stamp_ns * NS, hull[0:2], hull[2:4], hull[4:6], alert, parts)


class MrclamCpService:
    """One robot's CP (module docstring)."""

    def __init__(
        self,
        robot: str,
        config: RangeBearingCPConfig | None = None,
        tick_s: float = 0.1,
        cooperative: bool = True,
    ) -> None:
        if not tick_s > 0:
            raise ValueError(f"tick_s must be > 0 (got {tick_s})")
        self.robot = robot
        self.cfg = config or RangeBearingCPConfig()
        self.cooperative = cooperative
        self._subjects: dict[str, int] = {}
        self.cp = RangeBearingCP(self.cfg, {}, subject_of(robot, self._subjects))
        self.tick_ns = round(tick_s * 1e9)
        self._t0_ns: int | None = None  # the ticks' origin
        self._tick = 0  # index of the next tick
        self._now_ns = 0  # the latest stamp fed
        self._frame: list[RangeBearing] = []  # this robot's measurements of one stamp
        self.peers: dict[str, PoseBox] = {}  # the other robots' latest bounded boxes
        self.heard_from: set[str] = set()  # the robots that published a box
        self.counts: Counter = Counter()
        self.ticks = 0
        self.sightings_sent = 0
        self.sightings_heard = 0

    # -- inputs --------------------------------------------------------------------
    def feed(self, topic: str, msg: Any) -> list[tuple[str, Any]]:
        stamp = getattr(msg, "stamp_ns", None)
        if not isinstance(stamp, int):
            return []
        if stamp < self._now_ns:
            self.counts["back_in_time"] += 1
            return []
        out = self._until(stamp) if self._t0_ns is not None else []
        self._now_ns = stamp
        if topic == "landmark_map" and isinstance(msg, LandmarkMap):
            if self._t0_ns is None:
                self._t0_ns = stamp
            self.cp.landmarks = {
                int(i): (x, y, max(vx, 0.0) ** 0.5, max(vy, 0.0) ** 0.5)
                for i, x, y, vx, vy in zip(
                    msg.ids, msg.xs, msg.ys, msg.cov_xx, msg.cov_yy, strict=True
                )
            }
        elif topic == "velocity" and isinstance(msg, VelocityOdometry):
            self.cp.command(stamp * NS, msg.linear_mps, msg.angular_radps)
        elif (
            topic in RANGE_BEARING_TOPICS
            and isinstance(msg, RangeBearing)
            and msg.robot in ("", self.robot)
        ):
            if self._t0_ns is None:
                self.counts["before_map"] += 1
            else:
                self._frame.append(msg)
        return out

    def advance(self, stamp_ns: int) -> list[tuple[str, Any]]:
        """A clock: everything stamped up to ``stamp_ns`` is in, so the ticks and the
        frame up to it are handled now rather than at the next message (a robot whose
        odometry pauses still publishes its boxes)."""
        if self._t0_ns is None or stamp_ns < self._now_ns:
            return []
        out = self._until(stamp_ns + 1)
        self._now_ns = stamp_ns
        return out

    def feed_other(self, robot: str, topic: str, msg: Any) -> list[tuple[str, Any]]:
        """Another robot's box, or its sighting of this robot."""
        if robot == self.robot or not self.cooperative:
            return []
        if topic == "pose_box" and isinstance(msg, PoseBox) and msg.robot == robot:
            self.heard_from.add(robot)
            held = self.peers.get(robot)
            bounded = all(math.isfinite(v) for v in (msg.x.lo, msg.x.hi, msg.y.lo, msg.y.hi))
            if bounded and (held is None or msg.stamp_ns >= held.stamp_ns):
                self.peers[robot] = msg
        elif (
            topic == "peer_sighting"
            and isinstance(msg, PeerSighting)
            and msg.robot == self.robot
            and msg.observer == robot
        ):
            b = peer_box(msg.box, msg.pieces)
            if msg.box.stamp_ns != msg.stamp_ns:  # a box not taken at the measurement
                b = aged_to(b, msg.stamp_ns * NS, self.cfg)
            self.cp.hear(subject_of(robot, self._subjects), msg.range_m, msg.bearing_rad, b)
            self.sightings_heard += 1
        return []

    def drop_peer(self, robot: str) -> None:
        """A peer left: its box is no longer used."""
        self.peers.pop(robot, None)

    # -- the events before a stamp -------------------------------------------------
    def _until(self, stamp: int) -> list[tuple[str, Any]]:
        """The ticks and the frame stamped before ``stamp``, in time order."""
        out: list[tuple[str, Any]] = []
        assert self._t0_ns is not None  # the ticks start at the landmark map
        while True:
            tick = self._t0_ns + self._tick * self.tick_ns
            frame = self._frame[0].stamp_ns if self._frame else None
            if frame is not None and frame < tick and frame < stamp:
                out += self._solve_frame()
            elif tick < stamp:
                out.append(("pose_box", self._box(tick)))
                self._tick += 1
                self.ticks += 1
            else:
                return out

    def _box(self, stamp: int) -> PoseBox:
        """The box at ``stamp`` (the commands integrated up to it), as published."""
        cp = self.cp
        cp.advance(stamp * NS)
        b = cp.box()
        alert = round(cp.last_alert / NS) if math.isfinite(cp.last_alert) else 0
        return PoseBox(
            stamp,
            self.robot,
            Interval(float(b.x[0]), float(b.x[1])),
            Interval(float(b.y[0]), float(b.y[1])),
            Interval(float(b.th[0]), float(b.th[1])),
            status=b.status,
            alert_stamp_ns=max(0, alert),
        )

    def _solve_frame(self) -> list[tuple[str, Any]]:
        """This robot's measurements of one stamp: observed, solved, and the robots it
        saw told (with this robot's fresh box)."""
        frame, self._frame = self._frame, []
        stamp = frame[0].stamp_ns
        t = stamp * NS
        cp = self.cp
        cp.advance(t)
        obs: list[Observation | None] = []
        seen = []
        for m in frame:
            if m.landmark:
                if int(m.subject) not in cp.landmarks:
                    self.counts["unknown_landmark"] += 1
                    continue
                obs.append(cp.landmark(t, int(m.subject), m.range_m, m.bearing_rad))
            elif self.cooperative and m.target != self.robot:
                box = self.peers.get(m.target)
                if box is None:
                    self.counts["peer_box_unknown"] += 1
                else:
                    subj = subject_of(m.target, self._subjects)
                    obs.append(cp.peer_seen(t, subj, m.range_m, m.bearing_rad, peer_box(box)))
                if m.target in self.heard_from:
                    seen.append(m)
                else:
                    self.counts["sighting_of_silent_robot"] += 1
        obs = [o for o in obs if o is not None]
        if obs:
            cp.observe(t, obs)
        out: list[tuple[str, Any]] = []
        if not seen:
            return out
        if cp.latest() is None:
            self.counts["sighting_without_box"] += len(seen)
            return out
        mine = self._box(stamp)
        parts = cp.pieces() if self.cfg.peer_pieces else None
        pieces = () if parts is None else tuple(float(v) for p in parts for v in p.T.ravel())
        for m in seen:
            sighting = PeerSighting(
                stamp, m.target, self.robot, m.range_m, m.bearing_rad, mine, pieces
            )
            out.append(("peer_sighting", sighting))
            self.sightings_sent += 1
        return out
