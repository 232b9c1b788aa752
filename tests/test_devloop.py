"""The daemon's device loop (hilnav.devloop), on emulated devices run in this process:
every device whose port is a path is read by the loop itself (no thread per device); a
port that vanishes goes to a thread of its own, which reconnects it (the Pioneer's sync
handshake included) while the loop goes on reading the others, then hands it back; what
other threads queue is handled in arrival order with the reads."""

from __future__ import annotations

import threading
import time

import pytest

from hilnav.bus import free_tcp_port
from hilnav.config import parse_config
from hilnav.daemon import Daemon
from hilnav.devices import with_fake_ports
from hilnav.fakeset import build_fakes
from msgs import GroundTruth, Pose2D

DEVICES = {"arcos", "gyro", "ir", "gps"}


def _wait(cond, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return bool(cond())


def _device_threads() -> set[str]:
    return {t.name for t in threading.enumerate() if t.name.startswith("dev-")}


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("devloop")
    cfg = parse_config(
        {
            "name": "r1",
            "zenoh": {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"]},
            "log": {"dir": str(tmp)},
            "services": {"mapping": {"enabled": False}, "localization": {"enabled": False}},
            "simulation": {"seed": 3},
        },
        "<test>",
    )
    runner = build_fakes(cfg)
    runner.start()
    d = Daemon(with_fake_ports(cfg, runner.ports()), log_path=tmp / "r1.mcap")
    assert not d.cfg.simulated  # the devices are this process's fakes: no child process
    d.start()
    emulators = {e.name: e for e in runner.emulators}
    assert _wait(lambda: set(d.loop.looped) == DEVICES, 30.0), (d.loop.looped, d.errors)
    yield d, emulators
    d.stop()
    for e in runner.emulators:
        e.stop()


def count(d: Daemon, topic: str) -> int:
    return d.stats.by_topic.get(topic, 0)


def test_every_device_on_a_port_path_is_read_by_the_loop_not_a_thread(rig):
    d, _ = rig
    n = {t: count(d, t) for t in ("odometry", "gyro", "ir")}
    assert _wait(lambda: all(count(d, t) > n[t] + 5 for t in n), 5.0)
    assert set(d.loop.looped) == DEVICES
    assert not _device_threads()  # the opening threads handed their devices over and ended
    assert d.loop.reads > 0 and d.loop.batches > 0


def test_the_polled_devices_do_not_wake_the_loop_and_come_before_each_sip(rig):
    """The gyro, IR board and GPS sit on the loop's second epoll (never waited on): the
    100 Hz gyro is read several packets at a time, at the loop's turns (SIPs, ticks), yet
    read before each SIP, so no odometry message waits for its gyro sample."""
    d, _ = rig
    assert d.loop.polled == {"gyro", "ir", "gps"}  # every device but the Pioneer
    by_fd = {name: fd for fd, (name, _) in d.loop._by_fd.items()}
    assert d.loop._polled_fds == {by_fd["gyro"], by_fd["ir"], by_fd["gps"]}
    reads0, packets0, odo0 = count(d, "raw/gyro"), count(d, "gyro"), count(d, "odometry")
    turns0 = d.loop.reads
    assert _wait(lambda: count(d, "gyro") > packets0 + 200, 5.0)
    reads, packets = count(d, "raw/gyro") - reads0, count(d, "gyro") - packets0
    assert packets >= 2.5 * reads, (packets, reads)  # batches, not a wake-up per packet
    assert d.loop.reads - turns0 < packets  # fewer reads in all than gyro packets
    arrival = d.pipeline.heading.filter._align.arrival  # the heading filter's front end
    waited = arrival.waited
    assert _wait(lambda: count(d, "odometry") > odo0 + 15, 5.0)
    assert arrival.waited == waited  # the gyro was always in before the SIP


@pytest.mark.parametrize("device", ["gyro", "arcos"])
def test_a_vanished_port_is_reconnected_by_a_thread_while_the_loop_reads_the_others(rig, device):
    d, emulators = rig
    other = "odometry" if device == "gyro" else "gyro"
    own = "gyro" if device == "gyro" else "odometry"
    handovers = d.loop.handovers
    emulators[device].port.vanish()
    assert _wait(lambda: device not in d.loop.looped, 5.0)
    assert f"dev-{device}" in _device_threads()
    assert d.loop.handovers == handovers + 1
    n_other = count(d, other)
    time.sleep(0.5)
    assert count(d, other) > n_other + 3  # the loop went on with the others
    emulators[device].port.reappear()
    n_own = count(d, own)
    assert _wait(lambda: device in d.loop.looped and count(d, own) > n_own + 3, 15.0), d.errors
    assert _wait(lambda: f"dev-{device}" not in _device_threads(), 2.0)  # handed back
    assert d.drivers[device].reconnects >= 1


def test_queued_entries_are_handled_in_arrival_order_with_the_reads(rig):
    d, _ = rig
    seen: list[tuple[str, int]] = []
    real = d.runtime.emit

    def emit(topic, msg, log_ns, publish=True):
        if topic in ("truth", "gyro"):
            seen.append((topic, log_ns))
        return real(topic, msg, log_ns, publish)

    d.runtime.emit = emit
    try:
        for k in range(20):  # lazy entries: no wake-up of their own
            d.runtime.put("truth", GroundTruth(time.time_ns(), "r1", Pose2D(), 0.0, 0.0))
            time.sleep(0.013 + 0.001 * k)
        assert _wait(lambda: sum(t == "truth" for t, _ in seen) == 20, 2.0)
    finally:
        del d.runtime.emit
    truths = [ns for t, ns in seen if t == "truth"]
    assert truths == sorted(truths)  # in the order they were queued
    # handled as the loop comes round for the devices, between the reads: not saved up
    kinds = [t for t, _ in seen]
    last = len(kinds) - 1 - kinds[::-1].index("truth")
    assert "gyro" in kinds[kinds.index("truth") : last]


def test_a_turn_that_raises_is_counted_and_the_loop_goes_on(rig):
    """A driver that raises in the loop's read, and a timer that raises, are faults counted under
    ``loop``: the other devices are still read and the watchdog's heartbeat goes on."""
    d, _ = rig
    drv = d.drivers["gps"]
    real_fileno, real_tick = drv.fileno, d.loop.on_tick

    def broken_fileno():
        raise OSError("port in a state nobody expected")

    def broken_tick(now):
        raise RuntimeError("timer")

    faults = d.stats.faults.get("loop", 0)
    drv.fileno = broken_fileno
    d.loop.on_tick = broken_tick
    try:
        n = {t: count(d, t) for t in ("odometry", "gyro", "ir")}
        assert _wait(lambda: d.stats.faults.get("loop", 0) > faults + 3, 5.0), d.stats.faults
        assert _wait(lambda: all(count(d, t) > n[t] + 5 for t in n), 5.0)
        beat = d.motion.gate.stalls
        time.sleep(0.5)
        assert d.motion.gate.stalls == beat  # the heartbeat went on: no stall stop
    finally:
        drv.fileno = real_fileno
        d.loop.on_tick = real_tick
    assert d._loop_thread is not None and d._loop_thread.is_alive()


class _Recorder:
    """The consumer side of the loop (what RobotRuntime gives it), recording the reads."""

    def __init__(self) -> None:
        self.items: list = []
        self.faults: list = []

    def queued(self) -> bool:
        return False

    def take_queued(self) -> list:
        return []

    def handle_read(self, items, recv_ns, later=None, prompt=frozenset()) -> None:
        self.items.extend(items)

    def emit_later(self, later) -> None:
        pass

    def fault(self, where, exc) -> None:
        self.faults.append((where, exc))


class _PipeDevice:
    """A device on a real pipe: reads what is there, 4 KiB at most, as the drivers do."""

    def __init__(self) -> None:
        import os

        self.rfd, self.wfd = os.pipe()
        os.set_blocking(self.rfd, False)

    def fileno(self) -> int:
        return self.rfd

    def read(self, timeout_s: float) -> list:
        import os

        try:
            return [("raw/gyro", os.read(self.rfd, 4096))]
        except BlockingIOError:
            return []


def test_a_polled_device_that_delivers_more_than_a_read_is_read_again_in_the_turn():
    """A polled port with more bytes than one read takes (a busy CAN bus, a burst after a
    stall) is read again in the same turn, up to POLL_ROUNDS reads: nothing waits in the
    kernel's buffer for many turns, and a flooding port cannot hold the loop."""
    import os

    from hilnav.devloop import POLL_ROUNDS, DeviceLoop

    rec, dev, stop = _Recorder(), _PipeDevice(), threading.Event()
    loop = DeviceLoop(
        rec,
        read_device=lambda name, drv, t: drv.read(t),
        prompt_topics=frozenset(),
        start_thread=lambda name, drv: None,
        heartbeat=lambda: None,
        on_tick=lambda now: None,
        stop=stop,
        polled=frozenset({"gyro"}),
    )
    try:
        loop.adopt("gyro", dev)
        loop._turn()  # takes the device over
        assert loop.looped == ["gyro"] and loop._polled_fds == {dev.rfd}
        rec.items.clear()
        os.write(dev.wfd, b"\xff" * (4096 * (POLL_ROUNDS + 2)))
        loop._turn()
        got = sum(len(data) for _, data in rec.items)
        assert got == 4096 * POLL_ROUNDS  # read again and again, but bounded
        loop._turn()
        assert sum(len(data) for _, data in rec.items) == 4096 * (POLL_ROUNDS + 2)
        assert not rec.faults
    finally:
        loop._poll_later.close()
        loop._poller.close()
        loop.wake.close()
        os.close(dev.rfd)
        os.close(dev.wfd)
