"""hilnav.bus on real Zenoh sessions over loopback TCP (multicast scouting off)."""

from __future__ import annotations

import threading
import time

import pytest
import zenoh

import msgs
from hilnav.bus import Bus, ZenohSettings, free_tcp_port, key
from msgs import Interval, Pose2D, PoseBox, PoseEstimate, VelocityCommand


def _wait(cond, timeout_s: float = 5.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


@pytest.fixture
def pair():
    """Two buses: r1 listens, r2 connects; both only trust the fleet {r1, r2}."""
    port = free_tcp_port()
    a = Bus("r1", ZenohSettings.loopback(listen_port=port), fleet=["r2"])
    b = Bus("r2", ZenohSettings.loopback(connect_ports=[port]), fleet=["r1"])
    yield a, b, port
    b.close()
    a.close()


def _pose(i: int) -> PoseEstimate:
    return PoseEstimate(i, Pose2D(0.1 * i, -0.2, 0.3), (0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001))


def _publish_until(bus: Bus, topic: str, msg, got: list, robot: str | None = None) -> None:
    # Zenoh routes declarations asynchronously: repeat until the subscriber saw one.
    for _ in range(100):
        if robot:
            bus.publish_to(robot, topic, msg)
        else:
            bus.publish(topic, msg)
        if got:
            return
        time.sleep(0.05)


def test_settings_make_a_loopback_peer_with_multicast_off():
    s = ZenohSettings.loopback(listen_port=7447, connect_ports=[7448])
    conf = s.to_zenoh()
    assert conf.get_json("mode") == '"peer"'
    assert conf.get_json("listen/endpoints") == '["tcp/127.0.0.1:7447"]'
    assert conf.get_json("connect/endpoints") == '["tcp/127.0.0.1:7448"]'
    assert conf.get_json("scouting/multicast/enabled") == "false"


def test_settings_pass_user_password_and_access_control_through(tmp_path):
    creds = tmp_path / "users.txt"
    creds.write_text("r1:secret\n")
    s = ZenohSettings(
        usrpwd={"user": "r1", "password": "secret", "dictionary_file": str(creds)},
        access_control={"enabled": False, "default_permission": "allow"},
    )
    conf = s.to_zenoh()
    assert '"user":"r1"' in conf.get_json("transport/auth/usrpwd").replace(" ", "")
    assert conf.get_json("access_control/default_permission") == '"allow"'


def test_settings_start_from_a_native_json5_file(tmp_path):
    f = tmp_path / "zenoh.json5"
    f.write_text('{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:1"] } }')
    conf = ZenohSettings(config_file=str(f)).to_zenoh()
    assert conf.get_json("mode") == '"client"'
    assert conf.get_json("scouting/multicast/enabled") == "false"


def test_pose_from_another_fleet_robot_arrives_decoded(pair):
    a, b, _ = pair
    got: list = []
    a.subscribe("*", "pose", lambda robot, msg: got.append((robot, msg)))
    _publish_until(b, "pose", _pose(7), got)
    assert got, "no pose arrived"
    robot, msg = got[0]
    assert robot == "r2" and msg == _pose(7)
    assert a.stats.received >= 1 and a.stats.malformed == 0


def test_cmd_vel_to_a_robot_is_delivered_with_the_sender_checked(pair):
    a, b, _ = pair
    got: list = []
    a.subscribe("r1", "cmd_vel", lambda robot, msg: got.append(msg))
    cmd = VelocityCommand(1, 0.2, -0.1, source="r2")
    _publish_until(b, "cmd_vel", cmd, got, robot="r1")
    assert got and got[0] == cmd


def test_malformed_and_foreign_payloads_are_counted_not_raised(pair):
    a, _, port = pair
    got: list = []
    a.subscribe("*", "pose", lambda robot, msg: got.append((robot, msg)))
    a.subscribe("*", "pose_box", lambda robot, msg: got.append((robot, msg)))
    conf = ZenohSettings.loopback(connect_ports=[port]).to_zenoh()
    raw = zenoh.open(conf)
    try:
        good = msgs.encode(_pose(1))
        box = PoseBox(1, "r3", Interval(0, 1), Interval(0, 1), Interval(0, 0.1))
        for _ in range(100):
            raw.put(key("r2", "pose"), b"{not json", attachment=b"r2")  # malformed
            raw.put(key("r2", "pose"), b'{"stamp_ns": "x"}', attachment=b"r2")  # bad type
            raw.put(key("mallory", "pose"), good, attachment=b"mallory")  # not in fleet
            raw.put(key("r2", "pose"), good, attachment=b"mallory")  # sender not in fleet
            raw.put(key("r2", "pose"), good)  # no sender at all
            raw.put(key("r2", "pose_box"), msgs.encode(box), attachment=b"r2")  # claims r3
            if a.stats.malformed >= 2 and a.stats.foreign >= 4:
                break
            time.sleep(0.05)
        assert _wait(lambda: a.stats.malformed >= 2 and a.stats.foreign >= 4)
        assert got == []
        # the bus still works afterwards
        for _ in range(100):
            raw.put(key("r2", "pose"), good, attachment=b"r2")
            if got:
                break
            time.sleep(0.05)
        assert got and got[0] == ("r2", _pose(1))
    finally:
        raw.close()


def test_a_raising_callback_is_counted_and_the_bus_keeps_going(pair):
    a, b, _ = pair
    calls: list = []

    def bad(robot, msg):
        calls.append(msg)
        raise RuntimeError("boom")

    a.subscribe("*", "pose", bad)
    _publish_until(b, "pose", _pose(2), calls)
    assert _wait(lambda: a.stats.callback_errors >= 1)
    n = len(calls)
    b.publish("pose", _pose(3))
    assert _wait(lambda: len(calls) > n)


def test_liveliness_reports_arrival_and_departure():
    port = free_tcp_port()
    a = Bus("r1", ZenohSettings.loopback(listen_port=port), fleet=["r2"])
    try:
        b = Bus("r2", ZenohSettings.loopback(connect_ports=[port]))
        b.declare_alive()
        events: list = []
        lock = threading.Lock()

        def on(robot, alive):
            with lock:
                events.append((robot, alive))

        a.on_liveliness(on)  # history=True: the token already declared is reported
        assert _wait(lambda: ("r2", True) in events)
        b.close()
        assert _wait(lambda: ("r2", False) in events)
    finally:
        a.close()


def test_queryable_answers_and_an_empty_one_gives_none(pair):
    a, b, _ = pair
    latest = {"pose": _pose(5)}
    a.queryable("pose", lambda: latest.get("pose"))
    a.queryable("map", lambda: None)
    got = None
    for _ in range(100):  # until the queryable's declaration reached b (at most ~70 s)
        got = b.query("r1", "pose", timeout_s=0.5)
        if got is not None:
            break
        time.sleep(0.2)  # a get with no route yet returns at once, not after its timeout
    assert got == _pose(5)
    assert b.query("r1", "map", timeout_s=0.5) is None
    assert a.stats.queries_answered >= 1


def test_bad_names_are_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="one Zenoh key chunk"):
        Bus("r/1", ZenohSettings.loopback(listen_port=free_tcp_port()))
