"""``hilnav router`` on loopback: robots in client mode reach each other only through it;
a router's death is seen as peer loss, and a second router takes over."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest
from conftest import HILNAV, hilnav_env

from hilnav.bus import Bus, ZenohSettings, free_tcp_port
from hilnav.commands.router import router_settings
from hilnav.errors import CliError
from hilnav.fleet.launch import ROUTER_READY, read_line
from msgs import Interval, PoseBox


def _wait(cond, timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


def _router(port: int, *connect: int) -> subprocess.Popen:
    cmd = [*HILNAV, "router", "--listen", f"tcp/127.0.0.1:{port}"]
    for p in connect:
        cmd += ["--connect", f"tcp/127.0.0.1:{p}"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, env=hilnav_env())
    line = read_line(proc, 60.0)
    assert line is not None and line.startswith(ROUTER_READY), line
    return proc


def _stop(*procs: subprocess.Popen) -> None:
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(10)
        if p.stdout:
            p.stdout.close()


class _Robot:
    """A client bus that records the peers' boxes and liveliness changes."""

    def __init__(self, name: str, peer: str, ports: list[int]) -> None:
        eps = tuple(f"tcp/127.0.0.1:{p}" for p in ports)
        self.bus = Bus(name, ZenohSettings(mode="client", connect=eps), fleet=[peer])
        self.name, self.peer = name, peer
        self.boxes: list[PoseBox] = []
        self.live: list[tuple[str, bool]] = []
        self.bus.subscribe(peer, "pose_box", lambda r, m: self.boxes.append(m))
        self.bus.on_liveliness(lambda r, alive: self.live.append((r, alive)))
        self.bus.declare_alive()

    def send(self, i: int) -> None:
        b = PoseBox(i, self.name, Interval(0, 1), Interval(0, 1), Interval(0, 0.1))
        self.bus.publish("pose_box", b)

    def gets(self, other: _Robot, timeout_s: float = 10.0) -> bool:
        """``other`` sends until this robot has one more of its boxes."""
        n, i = len(self.boxes), 0
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            other.send(i)
            i += 1
            if len(self.boxes) > n:
                return True
            time.sleep(0.05)
        return False

    def lost_peer(self) -> bool:
        return (self.peer, False) in self.live

    def peer_alive_seen(self) -> bool:
        return (self.peer, True) in self.live

    def peer_back(self) -> bool:
        """The peer's token went and came back."""
        mine = [alive for r, alive in self.live if r == self.peer]
        return False in mine and mine[-1]


def test_two_clients_meet_only_through_the_router_and_see_it_die():
    port = free_tcp_port()
    router = _router(port)
    a = b = None
    try:
        a, b = _Robot("r1", "r2", [port]), _Robot("r2", "r1", [port])
        assert _wait(lambda: ("r2", True) in a.live and ("r1", True) in b.live)
        assert a.gets(b) and b.gets(a)
        # the clients listen nowhere: only the router's port is open among them
        router.send_signal(signal.SIGKILL)
        router.wait(10)
        assert _wait(lambda: a.lost_peer() and b.lost_peer()), (a.live, b.live)
        assert not a.gets(b, timeout_s=1.0)
    finally:
        for r in (a, b):
            if r is not None:
                r.bus.close()
        _stop(router)


def test_a_second_router_takes_over_when_the_first_is_killed():
    p1, p2 = free_tcp_port(), free_tcp_port()
    r1 = _router(p1)
    r2 = _router(p2, p1)  # the routers are linked
    a = b = None
    try:
        a, b = _Robot("r1", "r2", [p1, p2]), _Robot("r2", "r1", [p1, p2])
        assert _wait(lambda: ("r2", True) in a.live and ("r1", True) in b.live)
        assert a.gets(b) and b.gets(a)
        r1.send_signal(signal.SIGKILL)
        r1.wait(10)
        assert _wait(lambda: a.lost_peer() and b.lost_peer()), (a.live, b.live)
        # both reconnect through the second router: the peer comes back and data flows
        assert _wait(lambda: a.peer_back() and b.peer_back()), (a.live, b.live)
        assert a.gets(b) and b.gets(a)
    finally:
        for r in (a, b):
            if r is not None:
                r.bus.close()
        _stop(r1, r2)


def test_router_config_passthrough(tmp_path: Path):
    # a robot TOML: its [zenoh] table, mode forced to router, the command line's endpoints first
    toml = tmp_path / "r.toml"
    toml.write_text(
        '[zenoh]\nlisten = ["tcp/127.0.0.1:7500"]\nconnect = ["tcp/127.0.0.1:7501"]\n'
        '[zenoh.extra]\n"transport/unicast/max_links" = 2\n'
    )
    s = router_settings([], [], str(toml))
    assert (s.mode, s.listen, s.connect) == (
        "router",
        ("tcp/127.0.0.1:7500",),
        ("tcp/127.0.0.1:7501",),
    )
    conf = s.to_zenoh()
    assert json.loads(conf.get_json("mode")) == "router"
    assert json.loads(conf.get_json("transport/unicast/max_links")) == 2
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    s = router_settings(["tcp/127.0.0.1:7600"], [], str(toml))
    assert s.listen == ("tcp/127.0.0.1:7600",) and s.connect == ("tcp/127.0.0.1:7501",)
    # a native Zenoh JSON5 file is the base, untouched where the command line says nothing
    j5 = tmp_path / "z.json5"
    j5.write_text('{ listen: { endpoints: ["tcp/127.0.0.1:7700"] }, /* a comment */ }')
    conf = router_settings([], [], str(j5)).to_zenoh()
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7700"]
    assert json.loads(conf.get_json("mode")) == "router"
    # defaults: loopback only
    assert router_settings([], [], None).listen == ("tcp/127.0.0.1:7447",)
    with pytest.raises(CliError, match="--listen"):
        router_settings(["127.0.0.1:7447"], [], None)
    with pytest.raises(CliError, match="no such file"):
        router_settings([], [], str(tmp_path / "missing.json5"))


def test_a_client_listens_nowhere_and_needs_a_router():
    conf = ZenohSettings(
        mode="client", listen=("tcp/127.0.0.1:7447",), connect=("tcp/127.0.0.1:1",)
    )
    assert json.loads(conf.to_zenoh().get_json("listen/endpoints")) == []
    from hilnav.config import ConfigError, parse_config

    with pytest.raises(ConfigError, match="zenoh.mode = 'client' needs zenoh.connect"):
        parse_config({"zenoh": {"mode": "client"}}, "<t>")
    cfg = parse_config({"zenoh": {"mode": "client", "connect": ["tcp/127.0.0.1:7447"]}}, "<t>")
    assert cfg.zenoh.settings().mode == "client"


def test_the_daemon_meets_its_fleet_through_a_router():
    from hilnav.config import parse_config
    from hilnav.daemon import Daemon

    port = free_tcp_port()
    router = _router(port)
    ep = f"tcp/127.0.0.1:{port}"
    cfg = parse_config(
        {
            "name": "r1",
            "fleet": ["r2"],
            "zenoh": {"mode": "client", "connect": [ep]},
            "log": {"enabled": False},
            "services": {"mapping": {"enabled": False}},
            "devices": {d: {"enabled": False} for d in ("arcos", "ir", "gyro", "gps")},
        },
        "<test>",
    )
    d = Daemon(cfg)
    r2 = None
    try:
        d.start()
        r2 = _Robot("r2", "r1", [port])
        assert _wait(lambda: r2.peer_alive_seen())
        cp = d.pipeline.localization.cp
        end = time.monotonic() + 10
        while "r2" not in cp.peers and time.monotonic() < end:
            r2.send(time.time_ns())
            time.sleep(0.05)
        assert "r2" in cp.peers and "r2" in d.peers.alive
        r2.bus.close()  # r2 leaves: its token goes through the router
        r2 = None
        assert _wait(lambda: "r2" not in d.peers.alive)
        assert d.peers.dropped[-1] == ("r2", "token gone")
    finally:
        if r2 is not None:
            r2.bus.close()
        d.stop()
        _stop(router)
