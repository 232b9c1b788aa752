"""hilnav.bus_session: the robots of one process (a fleet host) on ONE Zenoh session, real
Zenoh over loopback TCP (peer mode, explicit endpoints, multicast scouting off): one
subscription per key expression, each sample decoded once and handed to every robot's
bus with its own fleet filter and counters; liveliness told to late subscribers; the
deferred session holds the samples until the consumer pumps them."""

from __future__ import annotations

import threading
import time

import pytest

import msgs
from hilnav.bus import Bus, ZenohSettings, free_tcp_port, key
from hilnav.bus_session import BusSession
from msgs import Interval, PoseBox


def _wait(cond, timeout_s: float = 10.0, pump: BusSession | None = None) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pump is not None:
            pump.pump()
        if cond():
            return True
        time.sleep(0.02)
    return cond()


def _box(robot: str, i: int) -> PoseBox:
    return PoseBox(i + 1, robot, Interval(0, 1), Interval(2, 3), Interval(-0.1, 0.1))


class _Got:
    """What a robot's callbacks received (thread-safe)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.msgs: list[tuple[str, PoseBox]] = []
        self.live: list[tuple[str, bool]] = []

    def on_box(self, robot: str, msg: PoseBox) -> None:
        with self.lock:
            self.msgs.append((robot, msg))

    def on_live(self, robot: str, alive: bool) -> None:
        with self.lock:
            self.live.append((robot, alive))


@pytest.fixture(params=[False, True], ids=["callback", "deferred"])
def host(request):
    """A host session (peer, listening on loopback) and a remote robot r9 connected to it."""
    port = free_tcp_port()
    shared = BusSession(ZenohSettings.loopback(listen_port=port), deferred=request.param)
    remote = Bus("r9", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1", "r2"])
    yield shared, remote
    remote.close()
    shared.close()


def _publish_until(bus: Bus, got: list, shared: BusSession, n: int = 1) -> None:
    # Zenoh routes declarations asynchronously: repeat until the subscribers saw one
    for i in range(200):
        bus.publish("pose_box", _box(bus.robot, i))
        shared.pump()
        if len(got) >= n:
            return
        time.sleep(0.05)


def test_two_robots_on_one_session_get_each_sample_decoded_once(host):
    shared, remote = host
    a, b = _Got(), _Got()
    r1 = Bus("r1", fleet=["r2", "r9"], shared=shared)
    r2 = Bus("r2", fleet=["r1"], shared=shared)  # r9 is not in r2's fleet
    r1.subscribe("*", "pose_box", a.on_box)
    r2.subscribe("*", "pose_box", b.on_box)
    _publish_until(remote, a.msgs, shared)
    assert a.msgs and a.msgs[0][0] == "r9" and isinstance(a.msgs[0][1], PoseBox)
    assert b.msgs == [] and r2.stats.foreign >= 1 and r1.stats.foreign == 0
    # a robot of the same process reaches the other through the session (local delivery),
    # and both take the SAME decoded message: one decoding for the whole process
    n1 = len(a.msgs)
    _publish_until(r2, b.msgs, shared)
    assert _wait(lambda: any(r == "r2" for r, _ in a.msgs[n1:]), pump=shared)
    got_a = {m.stamp_ns: m for r, m in a.msgs if r == "r2"}
    got_b = {m.stamp_ns: m for r, m in b.msgs if r == "r2"}
    same = set(got_a) & set(got_b)
    assert same and all(got_a[s] is got_b[s] for s in same)
    assert r1.stats.received == len(a.msgs) and r2.stats.received == len(b.msgs)
    assert shared.samples <= len(a.msgs) + len(b.msgs)
    # one robot's bus closing leaves the session (and the other robot) working
    r2.close()
    n = len(a.msgs)
    _publish_until(remote, a.msgs, shared, n + 1)
    assert len(a.msgs) > n and not shared.session.is_closed()
    r1.close()


def test_a_robot_subscribing_late_is_told_of_the_tokens_already_there(host):
    shared, remote = host
    early, late = _Got(), _Got()
    r1 = Bus("r1", fleet=["r2", "r9"], shared=shared)
    r1.on_liveliness(early.on_live)
    remote.declare_alive()
    assert _wait(lambda: ("r9", True) in early.live)
    r2 = Bus("r2", fleet=["r1", "r9"], shared=shared)
    r2.declare_alive()
    assert _wait(lambda: ("r2", True) in early.live)  # a token of the same session
    r2.on_liveliness(late.on_live)  # after the session's subscriber saw both tokens
    assert {("r9", True), ("r2", True)} <= set(late.live)
    remote.close()
    assert _wait(lambda: ("r9", False) in early.live and ("r9", False) in late.live)
    r1.close()
    r2.close()


def test_a_deferred_session_holds_the_samples_until_pumped():
    port = free_tcp_port()
    shared = BusSession(ZenohSettings.loopback(listen_port=port), deferred=True)
    raw = Bus("r9", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1"])
    got = _Got()
    r1 = Bus("r1", fleet=["r9"], shared=shared)
    try:
        r1.subscribe("*", "pose_box", got.on_box)
        _publish_until(raw, got.msgs, shared)
        assert got.msgs
        n = len(got.msgs)
        for i in range(5):
            raw.publish("pose_box", _box("r9", 1000 + i))
        time.sleep(0.5)
        assert len(got.msgs) == n  # nothing handed over without a pump
        assert _wait(lambda: len(got.msgs) >= n + 5, pump=shared)
        stamps = [m.stamp_ns for _, m in got.msgs[n:]]
        assert stamps == sorted(stamps)  # in arrival order
        # a malformed sample is counted by the bus that gets it, at the pump
        raw.session.put(key("r9", "pose_box"), b"{not json", attachment=b"r9")
        raw.session.put(key("r9", "pose_box"), msgs.encode(_box("r9", 2000)), attachment=b"r9")
        assert _wait(lambda: r1.stats.malformed >= 1 and len(got.msgs) >= n + 6, pump=shared)
    finally:
        r1.close()
        raw.close()
        shared.close()
