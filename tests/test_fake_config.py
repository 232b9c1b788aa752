"""One path from a robot's config to its emulated devices: every setting that shapes a
device reaches its fake, in-process (hilnav.fakeset.build_fakes) and through the daemon's
child process (the config handed over on stdin)."""

from __future__ import annotations

import math
import time

import pytest

from hilnav.bus import free_tcp_port
from hilnav.config import config_data, parse_config
from hilnav.daemon import Daemon
from hilnav.devices import FakeKnobs
from hilnav.errors import CliError
from hilnav.fakeset import build_fakes, override

CUSTOM = {
    "name": "r7",
    "geometry": {
        "wheel_base_m": 0.41,
        "ir_mounts": [[0.1, 0.0, 0.0], [0.0, 0.1, 90.0], [0.0, -0.1, -90.0]],
    },
    "devices": {
        "ir": {"board_id": 2, "rate_hz": 40, "adc_bits": 12, "vref_v": 3.3, "link": "serial"},
        "gyro": {"rate_hz": 50},
        "gps": {"datum": [48.1, 11.5]},
    },
    "simulation": {"plan": "paper_room", "seed": 9, "gps_rate_hz": 5.0, "corrupt": 0.02},
}


def _emulators(cfg):
    runner = build_fakes(cfg, FakeKnobs(drop=0.1))
    return runner, {e.name: e for e in runner.emulators}


def test_each_setting_reaches_its_emulator():
    cfg = parse_config(CUSTOM, "<test>")
    runner, emu = _emulators(cfg)
    assert set(emu) == {"arcos", "ir", "gyro", "gps"}
    robot = runner.world.robots["r7"]  # name
    assert robot.wheelbase_m == 0.41  # geometry.wheel_base_m
    assert runner.world.seed == 9 and runner.world.plan.name == "paper_room"
    ir = emu["ir"].config
    assert (ir.board_id, ir.rate_hz, ir.adc_bits, ir.vref_v) == (2, 40, 12, 3.3)
    assert ir.mounts == ((0.1, 0.0, 0.0), (0.0, 0.1, math.pi / 2), (0.0, -0.1, -math.pi / 2))
    assert emu["ir"].link == "serial"
    assert emu["gyro"].rate_hz == 50
    gps = emu["gps"]
    assert gps.rate_hz == 5.0 and (gps.datum.lat_deg, gps.datum.lon_deg) == (48.1, 11.5)
    f = emu["arcos"].faults
    assert f.corrupt_byte_prob == 0.02 and f.drop_packet_prob == 0.1
    assert emu["arcos"].cfg.name == "r7"


def test_the_can_link_is_served_behind_slcan_and_disabled_devices_are_not_served():
    data = {**CUSTOM, "devices": {"ir": {"link": "can"}, "gps": {"enabled": False}}}
    _, emu = _emulators(parse_config(data, "<test>"))
    assert emu["ir"].link == "slcan" and "gps" not in emu


def test_command_line_options_override_the_config_and_are_checked():
    cfg = override(parse_config(CUSTOM, "<t>"), plan="office", gyro_rate=200, seed=None)
    assert cfg.simulation.plan == "office" and cfg.devices.gyro.rate_hz == 200
    assert cfg.simulation.seed == 9  # not given: the config's
    with pytest.raises(CliError, match="--gps-rate.*simulation.gps_rate_hz"):
        override(cfg, gps_rate=20.0)


def test_the_resolved_config_round_trips_through_its_data():
    cfg = parse_config(CUSTOM, "<test>")
    assert parse_config(config_data(cfg), "<test>") == cfg


def test_the_daemon_hands_its_config_to_the_fake_process(tmp_path):
    """The bug this guards: with board_id 2 and sim ports the daemon got no IR scan,
    because the fake was started from flags that did not carry the board id."""
    port = free_tcp_port()
    data = {
        **CUSTOM,
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
        "log": {"enabled": False},
        "services": {"mapping": {"enabled": False}},
    }
    d = Daemon(parse_config(data, "<test>"))
    d.start()
    try:
        end = time.monotonic() + 20
        seen = d.stats.by_topic
        while time.monotonic() < end and min(seen.get(t, 0) for t in ("ir", "gps", "gyro")) < 5:
            time.sleep(0.1)
        assert d.stats.by_topic.get("ir", 0) >= 5, d.drivers["ir"].diagnostics(0)
        assert seen.get("gyro", 0) >= 5 and seen.get("gps", 0) >= 5
    finally:
        d.stop()
    assert d.fake is not None and d.fake.proc.returncode is not None
